"""`sigmarl sweep` overrides read by Hydra's own parser: list values, range(), quoted strings,
the models=/seeds= shorthands, and evaluation settings checked before anything trains."""

from __future__ import annotations

import pandas as pd
import pytest
import torch

from sigmarl.cli import main
from sigmarl.errors import SigmarlError
from sigmarl.resources import granted_threads
from sigmarl.sweep import _fixed, _jobs, _prepare_store, summarise, sweep_overrides

ALL_PRESETS = ("obs=full,no_ego_view,no_vertices,no_distance_to_agents,no_distance_to_boundaries,"
               "no_distance_to_center_line")


def launcher(out: list[str], cores: int) -> tuple[int, int]:
    """(hydra.launcher.n_jobs the sweep chose, threads each joblib job takes on `cores`)."""
    get = {o.split("=", 1)[0]: o.split("=", 1)[1] for o in out}
    assert "threads" not in get  # set in each job from its grant
    n_jobs = int(get["hydra.launcher.n_jobs"])
    return n_jobs, granted_threads({"n_jobs": n_jobs}, {}, cores=cores)


def test_list_values_are_plain_values_not_sweeps():
    user = ["eval.scenarios=[CPM,Roundabout]", "network.hidden=[128,128]"]
    out = sweep_overrides(user, cores=2)
    assert out[:2] == user and ALL_PRESETS in out
    assert launcher(out, 2) == (2, 1)  # 6 jobs (the models), not 6 x 2 x 2
    assert _fixed(out) == [*user, "seed=0"]
    jobs = _jobs(out)
    assert len(jobs) == 6 and all(len(j) == 1 and j[0].startswith("obs=") for j in jobs)


@pytest.mark.parametrize(("seeds", "values"), [
    ("seed=range(3)", ["0", "1", "2"]),
    ("seed=range(2,8,3)", ["2", "5"]),
    ("seed=0,1,2,3", ["0", "1", "2", "3"]),
    ("seeds=range(1,4)", ["1", "2", "3"]),
    ("seeds=[0,1,2]", ["0", "1", "2"]),
    ("seeds=7", ["7"]),
])
def test_seed_sweeps_count_their_jobs(seeds, values):
    out = sweep_overrides([seeds], cores=64)
    n = 6 * len(values)
    assert launcher(out, 64) == (n, 64 // n)
    jobs = [dict(o.split("=", 1) for o in job) for job in _jobs(out)]
    seeds_of_jobs = [j.get("seed") for j in jobs]
    if len(values) == 1:  # a single seed is a plain value, the same for every job
        assert set(seeds_of_jobs) == {None} and f"seed={values[0]}" in _fixed(out)
    else:
        assert sorted(set(seeds_of_jobs)) == sorted(values)
    assert len({(j["obs"], j.get("seed")) for j in jobs}) == len(jobs) == n


def test_models_shorthand_list_scalar_and_range_of_seeds():
    out = sweep_overrides(["models=[M0,M4]", "seeds=range(3)"], cores=16)
    assert "obs=full,no_distance_to_boundaries" in out and "seed=0,1,2" in out
    assert launcher(out, 16) == (6, 2)
    out = sweep_overrides(["models=M1"], cores=4)
    assert "obs=no_ego_view" in out and launcher(out, 4) == (1, 4)


def test_quoted_strings_keep_their_commas():
    out = sweep_overrides(["tracking.experiment='a,b'", "models=[M0]"], cores=4)
    assert "tracking.experiment='a,b'" in _fixed(out) and launcher(out, 4) == (1, 4)
    # A sweep over quoted values: each value keeps its quotes, so Hydra reads it back whole.
    out = sweep_overrides(['tracking.experiment="x y",z', "models=[M0]"], cores=4)
    assert _jobs(out) == [['tracking.experiment="x y"'], ["tracking.experiment=z"]]


def test_every_swept_key_multiplies_the_jobs():
    out = sweep_overrides(["ppo.lr=1e-4,2e-4", "models=[M0,M1,M2]"], cores=64)
    assert launcher(out, 64)[0] == 6 and len(_jobs(out)) == 6


@pytest.mark.parametrize(("user", "message"), [
    (["models=[M9]"], "unknown model"),
    (["models=[M0]", "obs=full"], "give either models=[...] or obs=..., not both"),
    (["seeds=[0]", "seed=1"], "give either seeds=[...] or seed=..., not both"),
    (["seeds=[]"], "seeds=[] selects no jobs"),
    (["seed=interval(0,1)"], "a sweep needs discrete values"),
    (["eval.scenarios=[CPM"], "bad override"),
])
def test_bad_sweep_overrides(user, message):
    with pytest.raises(SigmarlError, match=message.replace("[", r"\[").replace("]", r"\]")):
        sweep_overrides(user)


@pytest.mark.parametrize(("override", "message"), [
    ("eval.n_sims=0", "eval.n_sims must be positive, got 0"),
    ("eval.steps=-5", "eval.steps must be positive, got -5"),
    ("eval.scenarios=[CPM,Nowhere]", "unknown scenario(s) 'Nowhere'; choose from CPM, Intersection"),
    ("eval.scenarios=[]", "eval.scenarios is empty"),
    ("eval.checkpoint=last", "eval.checkpoint must be 'best' or 'final'"),
])
def test_bad_evaluation_settings_end_the_sweep_before_training(tmp_path, monkeypatch, capsys, override, message):
    monkeypatch.chdir(tmp_path)
    rc = main(["sweep", "study=quick", "models=[M0]", override, "tracking.enabled=false",
               f"runs_root={tmp_path}/runs"])
    assert rc == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1
    assert not (tmp_path / "runs").exists() and not (tmp_path / "multirun").exists()


def test_a_bad_value_inside_a_sweep_is_caught_too(tmp_path):
    out = sweep_overrides(["eval.n_sims=4,0", "models=[M0]", "tracking.enabled=false",
                           f"runs_root={tmp_path}/runs"], cores=2)
    with pytest.raises(SigmarlError, match="eval.n_sims must be positive, got 0"):
        _prepare_store(out)


def test_jobs_that_would_share_a_run_folder_are_refused(tmp_path):
    out = sweep_overrides(["ppo.lr=1e-4,2e-4", "models=[M0]", "tracking.enabled=false",
                           f"runs_root={tmp_path}/runs"], cores=2)
    with pytest.raises(SigmarlError, match="would share the run folder"):
        _prepare_store(out)


def test_summary_lists_every_job_of_a_range(tmp_path, capsys):
    out = sweep_overrides(["seed=range(3)", "models=[M0,M2]", f"runs_root={tmp_path}"], cores=2)
    (tmp_path / "M2" / "seed1").mkdir(parents=True)
    (tmp_path / "M2" / "seed1" / "evaluated.txt").touch()
    assert summarise(out) == 1  # five jobs unfinished
    lines = [line for line in capsys.readouterr().out.splitlines() if "seed " in line]
    assert len(lines) == 6
    assert sum("trained and evaluated" in line for line in lines) == 1
    assert any(line.split()[:4] == ["M2", "no_vertices", "seed", "1"] for line in lines)


@pytest.mark.slow
def test_sweep_with_list_values_end_to_end(tmp_path, monkeypatch, capsys):
    """`sigmarl sweep eval.scenarios=[CPM,Roundabout] network.hidden=[16,16]`: trains, evaluates
    on exactly those two scenarios, with that network."""
    monkeypatch.chdir(tmp_path)
    rc = main(["sweep", "eval.scenarios=[CPM,Roundabout]", "network.hidden=[16,16]", "models=[M0]",
               "ppo=smoke", "ppo.iterations=1", "eval.n_sims=1", "eval.steps=5", "tracking.enabled=false",
               f"runs_root={tmp_path}/runs"])
    assert rc == 0, capsys.readouterr().err
    run = tmp_path / "runs" / "M0" / "seed0"
    rows = pd.read_csv(run / "evaluation_rows.csv")
    assert list(rows["scenario"]) == ["CPM", "Roundabout"]
    state = torch.load(run / "final.pt", weights_only=False)
    assert list(state["config"]["network"]["hidden"]) == [16, 16]
    assert "M0     full" in capsys.readouterr().out
