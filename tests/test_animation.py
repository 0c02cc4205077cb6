"""Animations of evaluation rollouts: a trained checkpoint drives each requested scenario, one
GIF per scenario with one frame per step, at the scenario's agent count."""

from __future__ import annotations

import imageio.v3 as iio
import pytest

from sigmarl.compose import compose_config
from sigmarl.evaluation.animation import animate_checkpoint
from sigmarl.training import train


@pytest.mark.slow
def test_one_gif_per_scenario_with_a_frame_per_step(tmp_path):
    run = tmp_path / "run"
    train(compose_config(["ppo=smoke", "ppo.iterations=1", "tracking.enabled=false", f"run_dir={run}"]))
    out = animate_checkpoint(run / "best.pt", ["On-Ramp", "Intersection"], steps=6, seed=3,
                             out_dir=tmp_path / "report")
    assert set(out) == {"animation_On-Ramp", "animation_Intersection"}
    for scenario in ("On-Ramp", "Intersection"):
        path = tmp_path / "report" / "animations" / f"M0_{scenario}.gif"
        assert out[f"animation_{scenario}"] == path
        frames = iio.imread(path, index=None)
        assert frames.shape[0] == 6 and frames.shape[1] > 50 and frames.shape[2] > 50
