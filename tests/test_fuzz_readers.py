"""A fuzz harness for the checked readers: random cuts, byte flips, inserted bytes and wrong
shapes of each file a user or a crash can damage, taken from a committed run folder.

The property, for every damaged file: the reader returns what a resume can use, whole, or
raises one `SigmarlError` line that names the file (the CLI turns it into rc 2); never another
exception, a traceback or a resume past a lost iteration. The runs are derandomised, so CI
sees the same examples every time; `SIGMARL_FUZZ=explore` draws 20x more, at random, to look
for the next fault (`SIGMARL_FUZZ=explore pytest tests/test_fuzz_readers.py`).
"""

from __future__ import annotations

import json
import math
import os
import shutil
import tempfile
from pathlib import Path

import pytest
import torch
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sigmarl.errors import SigmarlError
from sigmarl.readers import (
    MAX_ITERATION,
    check_config_dir,
    read_json,
    read_run_config,
    read_training_curve,
)
from sigmarl.training import checkpoint, metrics_file

ROOT = Path(__file__).resolve().parents[1]
RUN = ROOT / "results" / "paper-budget" / "M0" / "seed0"
EXPLORE = os.environ.get("SIGMARL_FUZZ") == "explore"
FUZZ = settings(max_examples=2000 if EXPLORE else 100, derandomize=not EXPLORE, deadline=None,
                suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])

pytestmark = pytest.mark.slow


@st.composite
def damaged(draw, original: bytes) -> bytes:
    """`original` after one to three damages: a cut, flipped bytes, inserted or deleted bytes."""
    data = bytearray(original)
    for _ in range(draw(st.integers(1, 3))):
        kind = draw(st.sampled_from(["cut", "flip", "insert", "delete"]))
        at = draw(st.integers(0, max(len(data) - 1, 0)))
        if kind == "cut":
            del data[at:]
        elif kind == "flip" and data:
            data[at] ^= draw(st.integers(1, 255))
        elif kind == "insert":
            data[at:at] = draw(st.binary(min_size=1, max_size=8))
        elif data:
            del data[at:at + draw(st.integers(1, 16))]
    return bytes(data)


def _one_line_naming(error: SigmarlError, path: Path) -> None:
    text = str(error)
    assert "\n" not in text, text
    assert str(path) in text, text


def _write(tmp_path: Path, name: str, data: bytes) -> Path:
    path = tmp_path / name
    path.write_bytes(data)
    return path


@FUZZ
@given(data=damaged((RUN / "config.yaml").read_bytes()))
def test_a_damaged_run_config_is_read_or_refused_in_one_line(tmp_path, data) -> None:
    path = _write(tmp_path, "config.yaml", data)
    try:
        cfg = read_run_config(path)
    except SigmarlError as e:
        _one_line_naming(e, path)
    else:
        assert cfg.seed >= 0  # a config the run can use


METRICS = (RUN / "metrics.csv").read_bytes()
ITERATIONS = METRICS.decode().count("\n") - 1


@FUZZ
@given(data=damaged(METRICS), upto=st.integers(1, ITERATIONS))
def test_a_damaged_metrics_file_resumes_whole_or_is_refused(tmp_path, data, upto) -> None:
    """A resume at iteration `upto` gets every iteration 1..upto once, in order, or one line."""
    path = _write(tmp_path, "metrics.csv", data)
    try:
        rows = metrics_file.read(path, upto=upto)
    except SigmarlError as e:
        _one_line_naming(e, path)
    else:
        assert [it for it, _ in rows] == list(range(1, upto + 1))


@FUZZ
@given(data=damaged(METRICS))
def test_a_damaged_metrics_file_as_a_report_reads_it_is_whole_or_refused(tmp_path, data) -> None:
    """What a report averages: iterations 1..n once each, in order, every value finite, or one line."""
    path = _write(tmp_path, "metrics.csv", data)
    try:
        curve = read_training_curve(path)
    except SigmarlError as e:
        _one_line_naming(e, path)
    else:
        assert [it for it, _ in curve] == list(range(1, len(curve) + 1)) and len(curve) <= MAX_ITERATION
        assert all(math.isfinite(v) for _, values in curve for v in values.values())


def _checksummed(tmp: Path) -> bytes:
    """The committed resume point saved as training saves it today (with its checksum)."""
    state = torch.load(RUN / "checkpoint.pt", weights_only=True)
    checkpoint.save_atomic(state, tmp / "checkpoint.pt")
    return (tmp / "checkpoint.pt").read_bytes()


def _flat(x, prefix=""):
    if isinstance(x, dict):
        for k, v in x.items():
            yield from _flat(v, f"{prefix}/{k}")
    elif isinstance(x, (list, tuple)):
        for i, v in enumerate(x):
            yield from _flat(v, f"{prefix}/{i}")
    else:
        yield prefix, x


def _equal(a, b) -> bool:
    return torch.equal(a, b) if isinstance(a, torch.Tensor) and isinstance(b, torch.Tensor) else \
        (a == b or (isinstance(a, float) and math.isnan(a) and math.isnan(b)))


with tempfile.TemporaryDirectory() as _tmp:
    CHECKSUMMED = _checksummed(Path(_tmp))
    ORIGINAL = dict(_flat(checkpoint.load(Path(_tmp) / "checkpoint.pt", resume=True)))  # the undamaged file


@FUZZ
@given(data=damaged(CHECKSUMMED))
def test_a_checksummed_resume_point_loads_unchanged_or_is_refused(tmp_path, data) -> None:
    """The checksum's promise: whatever damage a resume point takes, what loads is exactly what
    was saved (every tensor, the optimiser's state, the random generators), or one line."""
    path = _write(tmp_path, "checkpoint.pt", data)
    try:
        state = checkpoint.load(path, resume=True)
    except SigmarlError as e:
        _one_line_naming(e, path)
    else:
        loaded = dict(_flat(state))
        assert loaded.keys() == ORIGINAL.keys() and all(_equal(loaded[k], ORIGINAL[k]) for k in ORIGINAL)


@FUZZ
@given(data=damaged((RUN / "checkpoint.pt").read_bytes()))
def test_a_damaged_checkpoint_loads_checked_or_is_refused(tmp_path, data) -> None:
    path = _write(tmp_path, "checkpoint.pt", data)
    try:
        state = checkpoint.load(path, resume=True)
    except SigmarlError as e:
        _one_line_naming(e, path)
    else:  # what passed holds the whole resume record (a flipped weight stays finite)
        assert set(checkpoint.RESUME_KEYS) <= state.keys()


JSON = st.recursive(st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=8),
                    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner, max_size=4),
                    max_leaves=12)
SEEDS_AUTO = {"seeds": dict, "previous": dict, "looks": list, "done": bool}


@FUZZ
@given(value=JSON, keep=st.dictionaries(st.sampled_from(sorted(SEEDS_AUTO)), JSON, max_size=4))
def test_a_json_record_of_the_wrong_shape_is_refused_in_one_line(tmp_path, value, keep) -> None:
    """The seeds=auto record's shape: any JSON value, or an object with some of its keys of any type."""
    for record in (value, keep):
        path = _write(tmp_path, "seeds_auto.json", json.dumps(record).encode())
        try:
            got = read_json(path, "the seeds=auto record", "move it away", SEEDS_AUTO)
        except SigmarlError as e:
            _one_line_naming(e, path)
        else:
            assert all(isinstance(got[k], kind) for k, kind in SEEDS_AUTO.items())


@FUZZ
@given(data=damaged((ROOT / "conf" / "study" / "paper.yaml").read_bytes()))
def test_a_damaged_config_folder_is_refused_in_one_line(tmp_path, data) -> None:
    folder = tmp_path / "my_conf"
    shutil.rmtree(folder, ignore_errors=True)  # hypothesis reuses tmp_path across examples
    (folder / "study").mkdir(parents=True)
    path = _write(folder / "study", "mine.yaml", data)
    try:
        check_config_dir(folder)
    except SigmarlError as e:
        _one_line_naming(e, path)
