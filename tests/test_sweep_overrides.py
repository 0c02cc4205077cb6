"""`sigmarl sweep` overrides read by Hydra's own parser: list values, range(), quoted strings,
the models=/seeds= shorthands, sweeps over any key, and every job's config checked before
anything trains."""

from __future__ import annotations

import re

import pandas as pd
import pytest
import torch

from sigmarl.cli import main
from sigmarl.errors import SigmarlError
from sigmarl.resources import granted_threads
from sigmarl.sweep import plan_sweep, summarise


def launcher(plan, cores: int) -> tuple[int, int]:
    """(hydra.launcher.n_jobs the sweep chose, threads each joblib job takes on `cores`)."""
    get = dict(o.split("=", 1) for o in plan.hydra)
    n_jobs = int(get["hydra.launcher.n_jobs"])
    return n_jobs, granted_threads({"n_jobs": n_jobs}, {}, cores=cores)


def test_list_values_are_plain_values_not_sweeps():
    user = ["eval.scenarios=[CPM,Roundabout]", "network.hidden=[128,128]"]
    plan = plan_sweep([*user, "tracking.enabled=false"], cores=2)
    assert plan.fixed[:2] == user
    assert launcher(plan, 2) == (2, 1)  # 6 jobs (the models), not 6 x 2 x 2
    assert len(plan.jobs) == 6 and all(j.overrides[:2] == user for j in plan.jobs)


@pytest.mark.parametrize(("seeds", "values"), [
    ("seed=range(3)", [0, 1, 2]),
    ("seed=range(2,8,3)", [2, 5]),
    ("seed=0,1,2,3", [0, 1, 2, 3]),
    ("seeds=range(1,4)", [1, 2, 3]),
    ("seeds=[0,1,2]", [0, 1, 2]),
    ("seeds=7", [7]),
])
def test_seed_sweeps_count_their_jobs(seeds, values):
    plan = plan_sweep([seeds, "tracking.enabled=false"], cores=64)
    n = 6 * len(values)
    assert launcher(plan, 64) == (n, 64 // n)
    assert sorted({j.seed for j in plan.jobs}) == values
    assert len({j.key for j in plan.jobs}) == len(plan.jobs) == n
    assert all(f"seed={j.seed}" in j.overrides for j in plan.jobs)


def test_models_shorthand_list_scalar_and_range_of_seeds():
    plan = plan_sweep(["models=[M0,M4]", "seeds=range(3)", "tracking.enabled=false"], cores=16)
    assert plan.labels == ["M0", "M4"] and launcher(plan, 16) == (6, 2)
    plan = plan_sweep(["models=M1", "tracking.enabled=false"], cores=4)
    assert plan.labels == ["M1"] and plan.jobs[0].variant == ["obs=no_ego_view"] and launcher(plan, 4) == (1, 4)


def test_presets_on_the_command_line_are_labelled_from_their_flags():
    plan = plan_sweep(["seed=3,4", "obs=full,no_distance_to_boundaries", "tracking.enabled=false"], cores=2)
    assert [j.key for j in plan.jobs] == ["M0/seed3", "M0/seed4", "M4/seed3", "M4/seed4"]


def test_quoted_strings_keep_their_commas(tmp_path):
    root = f"{tmp_path}/a,b"
    plan = plan_sweep(["tracking.enabled=false", f"runs_root='{root}'", "models=[M0]"], cores=4)
    assert f"runs_root='{root}'" in plan.fixed and launcher(plan, 4) == (1, 4)
    assert str(plan.config.runs_root) == root


def test_a_sweep_over_any_key_makes_one_variant_per_value(tmp_path):
    """The documented example: each width becomes a column (a label and a run folder)."""
    plan = plan_sweep(["study=quick", "models=[M0]", "network.hidden=[64,64],[128,128]",
                       "tracking.enabled=false", f"runs_root={tmp_path}"], cores=2)
    assert [j.key for j in plan.jobs] == ["M0_hidden-64-64/seed0", "M0_hidden-128-128/seed0"]
    assert plan.jobs[0].variant == ["obs=full", "network.hidden=[64,64]"]
    assert len({j.fingerprint for j in plan.jobs}) == 2
    assert plan.jobs[1].run_dir == f"{tmp_path}/M0_hidden-128-128/seed0"
    plan = plan_sweep(["ppo.lr=1e-4,3e-4", "models=[M0,M1,M2]", "tracking.enabled=false"], cores=64)
    assert len(plan.jobs) == 6 and plan.labels[:2] == ["M0_lr-0.0001", "M0_lr-0.0003"]


@pytest.mark.parametrize(("user", "message"), [
    (["models=[M9]"], "unknown model"),
    (["models=[M0]", "obs=full"], "give either models=[...] or obs=..., not both"),
    (["seeds=[0]", "seed=1"], "give either seeds=[...] or seed=..., not both"),
    (["seeds=[]"], "seeds=[] selects no jobs"),
    (["seed=interval(0,1)"], "a sweep needs discrete values"),
    (["eval.scenarios=[CPM"], "bad override"),
    (["model=X"], "model is set by the sweep itself"),
    (["study=widths", "network.hidden=[8,8]"], "network.hidden is set by variant W256"),
])
def test_bad_sweep_overrides(user, message):
    with pytest.raises(SigmarlError, match=message.replace("[", r"\[").replace("]", r"\]")):
        plan_sweep([*user, "tracking.enabled=false"])


@pytest.mark.parametrize(("override", "message"), [
    ("eval.n_sims=0", "eval.n_sims must be in 1..65536, got 0"),
    ("eval.steps=-5", "eval.steps must be in 1..1000000, got -5"),
    ("eval.scenarios=[CPM,Nowhere]", "unknown scenario 'Nowhere'; choose from CPM, Intersection"),
    ("eval.scenarios=[]", "eval.scenarios is empty"),
    ("eval.checkpoint=last", "eval.checkpoint='last' is not one of best, final"),
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
    with pytest.raises(SigmarlError, match=r"eval.n_sims must be in 1\.\.65536, got 0"):
        plan_sweep(["eval.n_sims=4,0", "models=[M0]", "tracking.enabled=false", f"runs_root={tmp_path}/runs"])


def test_a_run_folder_of_another_config_is_never_reused(tmp_path, capsys):
    """A lone `sigmarl train` with another network left M0/seed0 behind: the study's M0 is
    refused before anything trains, naming the difference."""
    runs = tmp_path / "runs"
    assert main(["train", "ppo=smoke", "ppo.iterations=1", "network.hidden=[8,8]", "tracking.enabled=false",
                 f"runs_root={runs}"]) == 0
    with pytest.raises(SigmarlError, match=r"M0/seed0 holds a run of another training config "
                                           r"\(network.hidden: \[8, 8\] -> \[256, 256\]"):
        plan_sweep(["models=[M0]", "ppo=smoke", "ppo.iterations=1", "tracking.enabled=false", f"runs_root={runs}"])
    # the same config is the same run: planned, to be resumed or skipped
    plan = plan_sweep(["models=[M0]", "ppo=smoke", "ppo.iterations=1", "network.hidden=[8,8]",
                       "tracking.enabled=false", f"runs_root={runs}"])
    assert plan.jobs[0].run_dir == f"{runs}/M0/seed0"


def test_summary_lists_every_job_of_a_range(tmp_path, capsys):
    plan = plan_sweep(["seed=range(3)", "models=[M0,M2]", "tracking.enabled=false", f"runs_root={tmp_path}"])
    (tmp_path / "M2" / "seed1").mkdir(parents=True)
    (tmp_path / "M2" / "seed1" / "evaluated.txt").touch()
    assert summarise(plan) == 1  # five jobs unfinished
    lines = [line for line in capsys.readouterr().out.splitlines() if "seed " in line]
    assert len(lines) == 6
    assert sum("trained and evaluated" in line for line in lines) == 1
    assert any(line.split()[:4] == ["M2", "obs=no_vertices", "seed", "1"] for line in lines)


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
    assert re.search(r"^  M0 +obs=full +seed 0 +trained and evaluated", capsys.readouterr().out, re.M)


def test_one_composition_per_variant_gives_what_each_seed_composed_alone_gives(tmp_path):
    from sigmarl.compose import compose_config, compose_seeds

    given = ["tracking.enabled=false", f"runs_root={tmp_path}", "eval.seed='${seed}'", "model=M2"]
    together = compose_seeds(given, [3, 7])
    assert [c.run_dir for c in together] == [f"{tmp_path}/M2/seed3", f"{tmp_path}/M2/seed7"]
    assert [c.eval.seed for c in together] == [3, 7]  # an interpolation of the seed follows it
    assert together == [compose_config([*given, f"seed={s}"]) for s in (3, 7)]


def test_the_summary_columns_line_up_however_long_a_variant(tmp_path, capsys):
    from sigmarl.sweep.launch import summarise

    plan = plan_sweep(["models=[M0,M4]", "seeds=[0,10]", "tracking.enabled=false", f"runs_root={tmp_path}"], cores=2)
    assert summarise(plan) == 1  # nothing trained: every job unfinished
    rows = [line for line in capsys.readouterr().out.splitlines() if line.startswith("  M")]
    assert len(rows) == 4 and len({row.index(" seed ") for row in rows}) == 1
    assert len({row.index("unfinished") for row in rows}) == 1 and len({row.index("[") for row in rows}) == 1
