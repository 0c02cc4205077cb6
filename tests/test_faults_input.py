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


def _own_scenario(tmp_path, name: str, text: str):
    conf = tmp_path / "conf"
    (conf / "scenario").mkdir(parents=True)
    path = conf / "scenario" / f"{name}.yaml"
    path.write_text(text)
    return conf, path


def test_f5_a_scenario_naming_an_unknown_map_is_refused_at_composition(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("SIGMARL_CONFIG_PATH", "")  # restored after
    conf, path = _own_scenario(tmp_path, "Lost", "map: nowhere\nn_agents: 4\n")
    line = one_line_exit_2(["--config-dir", str(conf), "train", "ppo=smoke", "eval.scenarios=[Lost]"], capsys)
    assert str(path) in line and "'nowhere'" in line and "paper_roundabout" in line  # the known maps
    assert sorted(p.name for p in tmp_path.iterdir()) == ["conf"]  # no run folder, no store


def test_f6_a_scenario_of_more_agents_than_its_map_holds_is_refused_at_composition(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("SIGMARL_CONFIG_PATH", "")  # restored after
    conf, path = _own_scenario(tmp_path, "Crowd", "map: paper_roundabout\nn_agents: 10000\n")
    line = one_line_exit_2(["--config-dir", str(conf), "sweep", "study=quick", "models=[M0]", "ppo=smoke",
                            "eval.scenarios=[Crowd]"], capsys)
    # the roundabout's routes are 87 vehicles long at the spawn spacing (sigmarl.env.spawn.capacity)
    assert str(path) in line and "10000 agents" in line and "at most 87" in line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["conf"]


def test_f6_training_agents_the_map_cannot_hold_leave_no_run_folder(tmp_path, capsys, monkeypatch):
    """Found by scripts/probe.py: the refusal came after the run folder and its lock were made."""
    monkeypatch.chdir(tmp_path)
    line = one_line_exit_2(["train", "ppo=smoke", "env.n_agents=10000", "tracking.enabled=false"], capsys)
    assert "10000 agents" in line and "at most 344" in line  # CPM's intersection (spawn.capacity)
    assert list(tmp_path.iterdir()) == []


def test_f6_a_scenario_that_fits_its_map_is_accepted(tmp_path, monkeypatch):
    from sigmarl.compose import compose_config
    from sigmarl.paths import add_user_conf_dir

    monkeypatch.setenv("SIGMARL_CONFIG_PATH", "")  # restored after
    conf, _ = _own_scenario(tmp_path, "Busy", "map: paper_roundabout\nn_agents: 87\n")
    add_user_conf_dir(conf)
    assert compose_config(["ppo=smoke", "eval.scenarios=[Busy]"]).eval.scenarios == ["Busy"]
