"""Every config key fuzzed, from the schema: no key is named here, so a key added to a config
record is fuzzed the day it is added. Each key is given a value of the wrong type, the values
just outside the range declared on its field (`sigmarl.config.ranges`), and, where it is a size,
absurd sizes; each must be refused in one line (SigmarlError, the CLI's exit code 2) while
composing, before any run folder or MLflow store exists.

In-process: Hydra composes the default tree once (as `sigmarl train` would), and each case is
that tree with one value merged in the way an override's value is (OmegaConf's typed merge),
then resolved and checked as `compose_config` does (`compose._finish`). The command-line path
of a few of them (the round's reproductions) is in test_faults_limits.py and the probes.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import os
import typing
from pathlib import Path
from typing import Any, get_type_hints

import pytest
from omegaconf import OmegaConf

from sigmarl.compose import _bad_override, _compose, _finish
from sigmarl.config import Config
from sigmarl.config.ranges import Range, range_of
from sigmarl.errors import SigmarlError

ABSURD = (10**12, 10**30)


def leaves(schema: type = Config, prefix: str = "") -> list[tuple[str, dataclasses.Field, Any]]:
    """(dotted key, field, annotated type) of every settable key of the schema."""
    out = []
    types = get_type_hints(schema)
    for f in dataclasses.fields(schema):
        if dataclasses.is_dataclass(types[f.name]):
            out += leaves(types[f.name], f"{prefix}{f.name}.")
        else:
            out.append((prefix + f.name, f, types[f.name]))
    return out


def wrong_type(annotation: Any) -> Any:
    """A value no key of this type takes: text for numbers, flags and containers, a list for text."""
    return [1, 2] if annotation is str else "not-a-value"


def _outside_numbers(rng: Range, integral: bool) -> list[Any]:
    out = []
    for end, is_open, down in ((rng.lo, rng.lo_open, True), (rng.hi, rng.hi_open, False)):
        if math.isinf(end):
            continue
        if is_open:
            out.append(int(end) if integral else float(end))
        elif integral:
            out.append(int(end) - 1 if down else int(end) + 1)
        else:
            out.append(math.nextafter(float(end), -math.inf if down else math.inf))
    return out


def outside(rng: Range, default: Any, element: Any) -> list[Any]:
    """The values just outside `rng` (for a key of `element`s; a list's or dict's values)."""
    if rng.choices:
        return ["no-such-" + rng.choices[0]]
    if rng.pattern:
        return [f"{default}:abc", f"x{default}"]
    return _outside_numbers(rng, element is int)


def element_type(annotation: Any) -> Any:
    args = typing.get_args(annotation)
    return args[-1] if args else annotation


def as_value(annotation: Any, element: Any, default: Any) -> Any:
    """`element` as a value of a key of this type: one element of a list, one entry of a dict."""
    origin = typing.get_origin(annotation)
    if origin is list:
        return [element]
    if origin is dict:
        return {next(iter(default), "key"): element}
    return element


def default_of(f: dataclasses.Field) -> Any:
    return f.default_factory() if f.default_factory is not dataclasses.MISSING else f.default


def cases() -> list[tuple[str, Any, str]]:
    """(key, value, what it tries) for every key of the schema."""
    out = []
    for key, f, annotation in leaves():
        out.append((key, wrong_type(annotation), "wrong type"))
        rng = range_of(f)
        if rng is None:
            continue
        element = element_type(annotation)
        for value in outside(rng, default_of(f), element):
            out.append((key, as_value(annotation, value, default_of(f)), f"just outside {rng.text()}"))
        if rng.size:
            out += [(key, as_value(annotation, n, default_of(f)), "absurd size") for n in ABSURD]
    return out


@pytest.fixture(scope="module")
def tree(tmp_path_factory):
    folder = tmp_path_factory.mktemp("fuzz")
    cwd = os.getcwd()
    os.chdir(folder)
    try:
        yield _compose([]), folder
    finally:
        os.chdir(cwd)


def composed_with(base, key: str, value: Any) -> Config:
    one = copy.deepcopy(base)
    with _bad_override():  # an override's value is merged so (Hydra's `key=value`), and refused so
        OmegaConf.update(one, key, value, merge=True)
    return _finish(one, OmegaConf.structured(Config))


def test_the_schema_declares_ranges_and_sizes():
    """The fuzz below has something to try: the keys the fifth round found unchecked declare ranges."""
    ranged = {key: range_of(f) for key, f, _ in leaves() if range_of(f)}
    assert ranged["ppo.gamma"].holds(1.0) and not ranged["ppo.gamma"].holds(math.nextafter(1.0, 2))
    assert not ranged["ppo.clip_epsilon"].holds(1.0) and not ranged["ppo.clip_epsilon"].holds(0.0)
    assert {"threads", "ppo.frames_per_iteration", "network.hidden"} <= {k for k, r in ranged.items() if r.size}
    assert len(cases()) > len(leaves()) + len(ranged)


def test_every_key_refuses_every_fuzzed_value_in_one_line(tree):
    base, folder = tree
    accepted, long = [], []
    for key, value, why in cases():
        try:
            composed_with(base, key, value)
        except SigmarlError as e:
            if "\n" in str(e) or len(str(e)) > 400 or key not in str(e):
                long.append(f"{key}={value!r} ({why}): {str(e)[:120]!r}")
        else:
            accepted.append(f"{key}={value!r} ({why})")
    assert not accepted, f"{len(accepted)} fuzzed values accepted: {accepted}"
    assert not long, f"refusals longer than a line, or not naming the key: {long}"
    # nothing was created: no run folder, no MLflow store, no report
    assert list(Path(folder).iterdir()) == []


def test_the_default_tree_itself_is_accepted(tree):
    base, _ = tree
    assert composed_with(base, "seed", 0).seed == 0
