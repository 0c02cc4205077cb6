"""A sweep adds no seed trained with other settings to a study's run folders (fault N2):
it refuses in one line, before anything trains, naming the settings that differ."""

from __future__ import annotations

from pathlib import Path

import pytest
from cli_errors import one_line_exit_2
from omegaconf import OmegaConf

from sigmarl.config import as_dict
from sigmarl.errors import SigmarlError
from sigmarl.sweep.plan import plan_sweep

STUDY = ["study=quick", "models=[M0]", "ppo=smoke", "tracking.enabled=false"]


def _trained_seed0(runs: Path) -> Path:
    """What a sweep of STUDY leaves for seed 0 (its config.yaml, as the job writes it)."""
    cfg = plan_sweep([*STUDY, f"runs_root={runs}", "seeds=[0]"], cores=1).jobs[0]
    from sigmarl.compose import compose_config

    composed = compose_config(cfg.overrides)
    folder = Path(cfg.run_dir)
    folder.mkdir(parents=True)
    (folder / "config.yaml").write_text(OmegaConf.to_yaml(as_dict(composed)))
    return folder


def test_a_seed_of_another_budget_is_refused_beside_the_studys_seeds(tmp_path):
    seed0 = _trained_seed0(tmp_path / "runs")
    plan = plan_sweep([*STUDY, f"runs_root={tmp_path / 'runs'}", "seeds=[0,3]"], cores=1)  # the same settings
    assert [j.key for j in plan.jobs] == ["M0/seed0", "M0/seed3"]
    with pytest.raises(SigmarlError) as refused:
        plan_sweep([*STUDY, f"runs_root={tmp_path / 'runs'}", "seeds=[3]", "ppo.iterations=40"], cores=1)
    line = str(refused.value)
    assert f"{seed0.parent} holds seed0, trained with other settings than seed(s) 3 (ppo.iterations: 4 -> 40)" in line
    assert not (seed0.parent / "seed3").exists()


def test_the_sweep_command_says_it_in_one_line(tmp_path, capsys):
    _trained_seed0(tmp_path / "runs")
    line = one_line_exit_2(["sweep", *STUDY, f"runs_root={tmp_path / 'runs'}", "seeds=[3]", "ppo.iterations=40"],
                           capsys)
    assert "trained with other settings" in line and "ppo.iterations: 4 -> 40" in line
    assert sorted(p.name for p in (tmp_path / "runs" / "M0").iterdir()) == ["seed0"]
