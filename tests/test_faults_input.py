"""Bad input found by the third reliability round: each ends in one line naming what to fix,
exit code 2, before any run folder or MLflow run exists."""

from __future__ import annotations

import pytest
from cli_errors import one_line_exit_2


@pytest.mark.parametrize("name", ["../../etc", "a/b", "..", "a\\b"])
def test_f1_an_experiment_name_is_a_folder_name_inside_runs(name, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    line = one_line_exit_2(["train", "ppo=smoke", f"tracking.experiment={name}"], capsys)
    assert "tracking.experiment" in line
    assert list(tmp_path.iterdir()) == []  # no run folder above or here, no mlflow.db


@pytest.mark.parametrize("seeds", ["seeds=[abc]", "seeds=[1.5]", "seeds=[-1]", "seed=abc"])
def test_f2_a_seed_that_is_not_a_whole_number_is_one_line(seeds, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    line = one_line_exit_2(["sweep", "study=quick", "models=[M0]", seeds], capsys)
    assert "seed" in line
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("override, key", [
    ("ppo.lr=nan", "ppo.lr"),
    ("map.lane_width=nan", "map.lane_width"),
    ("ppo.gamma=inf", "ppo.gamma"),
    ("env.spawn_end_fraction=nan", "env.spawn_end_fraction"),
    ("map.arm_lengths=[1.0,nan]", "map.arm_lengths[1]"),
])
def test_f3_every_float_key_is_finite(override, key, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    line = one_line_exit_2(["train", "ppo=smoke", override], capsys)
    assert f"{key} must be a finite number" in line
    assert list(tmp_path.iterdir()) == []  # no FAILED MLflow run: nothing was created
