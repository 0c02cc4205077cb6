"""`Run` owns its folder: no other module joins a run folder and one of its file names, and
interruptions are handled through the one helper in `sigmarl.errors`."""

import re
import signal
from pathlib import Path

import pytest

from sigmarl import run as run_mod
from sigmarl.errors import Terminated, end_status, exit_code, interruption, raise_if_interrupted

SRC = Path(run_mod.__file__).parents[1]  # the package (sigmarl.run is a package: run/__init__.py)
NAMES = {k: v for k, v in vars(run_mod).items() if k.endswith(("_FILE", "_META")) and isinstance(v, str)}
EXEMPT = {"run/__init__.py"}
JOIN = re.compile(r"/\s*(?:\w+\.)?(" + "|".join(NAMES) + r")\b|/\s*[\"'](" +
                  "|".join(re.escape(v) for v in NAMES.values()) + r"|seeds_auto\.json)[\"']")


def test_no_module_but_run_joins_a_folder_and_a_run_file():
    found = []
    for path in sorted(SRC.rglob("*.py")):
        rel = path.relative_to(SRC).as_posix()
        if rel in EXEMPT:
            continue
        for n, line in enumerate(path.read_text().splitlines(), 1):
            if JOIN.search(line.split("#")[0]):
                found.append(f"{rel}:{n}: {line.strip()}")
    assert not found, "run-folder paths built outside sigmarl.run:\n" + "\n".join(found)


def test_the_pattern_sees_each_way_of_writing_a_path():
    for line in ('run_dir / ROWS_FILE', 'd / ckpt.RESUME_FILE', 'x / "config.yaml"', "p/'metrics.csv'"):
        assert JOIN.search(line), line
    assert not JOIN.search("run.rows_file")


def test_run_names_every_file_of_its_folder(tmp_path):
    run = run_mod.Run(tmp_path / "M0" / "seed0")
    assert run.config_file == tmp_path / "M0" / "seed0" / "config.yaml"
    assert (run.metrics_file.name, run.resume_file.name, run.rows_file.name, run.rows_meta_file.name) == (
        "metrics.csv", "checkpoint.pt", "evaluation_rows.csv", "evaluation.json")
    assert run.checkpoint("best").name == "best.pt" and run.checkpoint("final").name == "final.pt"
    assert run.failure() is None
    run.mark_failed("Traceback...\nValueError: boom\n")
    assert run.failure() == "ValueError: boom" and run.state == "failed"
    run.clear_failed()
    run.mark_done("abc")
    assert run.done_file.read_text() == "abc\n" and run.state == "evaluated"


def test_one_interrupt_policy():
    ki, term, fail = KeyboardInterrupt(), Terminated(), ValueError("x")
    assert interruption(ki) is ki and interruption(fail) is None
    wrapped = RuntimeError("tensordict to boolean")
    wrapped.__context__ = ki
    assert isinstance(interruption(wrapped), KeyboardInterrupt)
    assert (end_status(ki), end_status(term), end_status(fail)) == ("KILLED", "KILLED", "FAILED")
    assert exit_code(ki) == ("interrupted", 128 + signal.SIGINT)
    assert exit_code(term) == ("terminated", 128 + signal.SIGTERM)
    raise_if_interrupted(fail)  # a failure passes through
    with pytest.raises(KeyboardInterrupt) as raised:
        raise_if_interrupted(wrapped)
    assert raised.value.__cause__ is wrapped
