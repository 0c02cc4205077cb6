"""Every config key has one line of help (the string literal after its field), and
`sigmarl --info KEY` and `sigmarl train --help` show it."""

from __future__ import annotations

import importlib.util
import sys
import textwrap

import pytest

from sigmarl.cli import main
from sigmarl.config.help import key_help
from sigmarl.config.suggest import schema_keys


def test_every_config_key_has_a_help_line():
    keys = key_help()
    assert [k.key for k in keys] == schema_keys()  # every key of the schema, in its order
    missing = [k.key for k in keys if not k.help]
    assert not missing, (f"config keys without a help line: {missing}; write a string literal on the "
                         "line after the field in its group's module of src/sigmarl/config/")
    too_long = [k.key for k in keys if not k.group and (len(k.help) > 250 or "\n" in k.help)]
    assert not too_long, f"help lines longer than one line: {too_long}"


def test_a_field_without_a_docstring_is_found(tmp_path, monkeypatch):
    source = textwrap.dedent('''
        from dataclasses import dataclass, field

        @dataclass
        class Inner:
            """A group."""

            width: int = 3
            """How wide."""
            depth: float = 0.5  # a comment is no help line

        @dataclass
        class Outer:
            inner: Inner = field(default_factory=Inner)
            names: list[str] = field(default_factory=lambda: ["a"])
            """Some names."""
        ''')
    (tmp_path / "schema_example.py").write_text(source)
    spec = importlib.util.spec_from_file_location("schema_example", tmp_path / "schema_example.py")
    module = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, "schema_example", module)
    spec.loader.exec_module(module)
    keys = {k.key: k for k in key_help(module.Outer)}
    assert list(keys) == ["inner", "inner.width", "inner.depth", "names"]
    assert keys["inner"].help == "A group." and keys["inner"].group
    assert (keys["inner.width"].type, keys["inner.width"].default, keys["inner.width"].help) == ("int", 3, "How wide.")
    assert keys["inner.depth"].help == ""
    assert (keys["names"].type, keys["names"].default) == ("list[str]", ["a"])


def test_info_key_prints_type_default_and_help(capsys):
    with pytest.raises(SystemExit) as e:
        main(["--info", "ppo.lr"])
    assert e.value.code == 0
    assert capsys.readouterr().out.strip() == (
        "ppo.lr (float, default 0.0002): Learning rate at the first iteration (linear decay to lr_final).")


def test_info_group_lists_its_keys(capsys):
    with pytest.raises(SystemExit):
        main(["--info", "eval"])
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("eval: Evaluation protocol")
    assert [line.split(" ")[0] for line in lines[1:]] == [
        "eval.scenarios", "eval.n_sims", "eval.steps", "eval.seed", "eval.checkpoint"]
    assert "eval.n_sims (int, default 32): " in lines[2]


def test_info_unknown_key_is_one_line_and_rc_2(capsys):
    with pytest.raises(SystemExit) as e:
        main(["--info", "ppo.lx"])
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "did you mean ppo.lr?" in err


def test_train_help_lists_every_key(capsys):
    with pytest.raises(SystemExit):
        main(["train", "--help"])
    out = capsys.readouterr().out
    for k in key_help():
        if not k.group:
            assert f"    {k.key}=" in out
    assert "    rules.timeout_terminal=False  Paper: a training time-out is terminal" in out


def test_a_computed_float_default_is_shown_as_typed():
    from sigmarl.config.help import describe, shown

    assert shown(0.15 * 7 / 30) == "0.035" and shown(2e-4) == "0.0002" and shown([256, 256]) == "[256, 256]"
    assert shown(1e-12) == "1e-12" and shown(True) == "True" and shown("cpm") == "'cpm'"
    assert "default 0.035)" in describe("env.reward.deviation_scale")
