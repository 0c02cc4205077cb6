"""A command-line sweep's variants are a sub-study of their own: the report the sweep prints
selects exactly them with the baseline stated, the study's own report keeps its own columns, a
swept value that composes to the variant's own config reuses its runs, and `--models` keeps the
study's baseline or is told another with study.baseline=."""

from __future__ import annotations

import shlex

import pytest
from cli_errors import one_line_exit_2

from sigmarl.cli import main
from sigmarl.compose import compose_config
from sigmarl.run import Run
from sigmarl.sweep import plan_sweep
from sigmarl.sweep.launch import report_hint


def _hint(plan) -> list[str]:
    return shlex.split(report_hint(plan))


def test_a_swept_default_is_the_variant_itself_and_the_hint_selects_the_sweep(tmp_path):
    plan = plan_sweep(["study=quick", "models=[M0]", "env.vehicle.max_speed=0.6,0.8", "tracking.enabled=false",
                       f"runs_root={tmp_path}"], cores=2)
    # 0.8 is max_speed's default: that job is M0's own, in M0's folder, never a second M0
    assert plan.labels == ["M0_max_speed-0.6", "M0"] and plan.twins == {"M0_max_speed-0.8": "M0"}
    assert [j.run_dir for j in plan.jobs] == [f"{tmp_path}/M0_max_speed-0.6/seed0", f"{tmp_path}/M0/seed0"]
    assert plan.jobs[1].fingerprint == compose_config(["study=quick", "model=M0", "obs=full"]).fingerprint
    words = _hint(plan)
    assert words[2:4] == ["--models", "M0_max_speed-0.6,M0"] and words[-1] == "study.baseline=M0"


def test_without_the_default_the_baseline_is_the_first_value_swept_from_the_studys_and_stated(tmp_path):
    plan = plan_sweep(["study=quick", "models=[M4,M0]", "env.vehicle.max_speed=0.6,0.7", "tracking.enabled=false",
                       f"runs_root={tmp_path}"], cores=2)
    assert plan.twins == {} and len(plan.jobs) == 4
    words = _hint(plan)
    assert "M4_max_speed-0.6,M4_max_speed-0.7,M0_max_speed-0.6,M0_max_speed-0.7" in words
    assert words[-1] == "study.baseline=M0_max_speed-0.6"  # the study's M0, not the first listed
    assert compose_config(["study=quick", "study.baseline=M0_max_speed-0.6"]).study.baseline == "M0_max_speed-0.6"
    # a study's own sweep (no swept key) still prints the study's report
    assert "--models" not in _hint(plan_sweep(["study=quick", "models=[M0]", "tracking.enabled=false"], cores=2))


@pytest.mark.parametrize(("args", "message"), [
    (["--models", "M4,M1"], "--models M4,M1 leaves out study 'quick''s baseline M0: add it, or say which column"),
    (["--models", "M4,M1", "study.baseline=M2"], "study.baseline=M2 is not among --models M4,M1"),
])
def test_models_without_the_baseline_is_refused_in_one_line(tmp_path, capsys, args, message):
    line = one_line_exit_2(["report", "--from", str(tmp_path), "study=quick", "tracking.enabled=false", *args],
                           capsys)
    assert message in line


@pytest.mark.slow
def test_the_max_speed_sequence_reports_the_sweep_apart_and_reuses_m0(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    common = ["study=quick", "ppo.iterations=1", "eval.n_sims=2", "eval.steps=20", "eval.scenarios=[Roundabout]",
              f"runs_root={tmp_path}/runs", f"tracking.tracking_uri=sqlite:///{tmp_path}/mlflow.db"]
    assert main(["sweep", "models=[M0]", *common]) == 0
    m0 = Run(tmp_path / "runs" / "M0" / "seed0")
    before = m0.final_file.stat().st_mtime_ns
    capsys.readouterr()
    assert main(["sweep", "models=[M0]", "env.vehicle.max_speed=0.6,0.8", *common]) == 0
    out = capsys.readouterr().out
    assert m0.final_file.stat().st_mtime_ns == before  # M0's twin was not trained again
    assert "M0_max_speed-0.8 is M0's training config" in out
    assert not (tmp_path / "runs" / "M0_max_speed-0.8").exists()
    words = shlex.split(next(ln for ln in out.splitlines() if ln.startswith("next: ")).removeprefix("next: "))
    assert main([*words[1:], "--no-figures", "--out", str(tmp_path / "sub")]) == 0
    table = (tmp_path / "sub" / "table.md").read_text(encoding="utf-8")
    assert "| Scenario | Metric | M0_max_speed-0.6 | M0 |" in table and "trained otherwise than M0" in table
    assert main(["report", *common, "--no-figures", "--out", str(tmp_path / "study")]) == 0
    table = (tmp_path / "study" / "table.md").read_text(encoding="utf-8")
    assert "| Scenario | Metric | M0 |" in table and "M0_max_speed" not in table
