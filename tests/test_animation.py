"""Animations of evaluation rollouts: a trained checkpoint drives each requested scenario, one
GIF per scenario with one frame per step, at the scenario's agent count."""

from __future__ import annotations

import re
from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pandas as pd
import pytest
from PIL import Image

from sigmarl.compose import compose_config
from sigmarl.evaluation.animation import animate, animate_checkpoint
from sigmarl.evaluation.rollout import evaluate_policy
from sigmarl.scenarios import scenario as scenario_of
from sigmarl.training import checkpoint as ckpt
from sigmarl.training import train
from sigmarl.training.loop import load_policy


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


ROUNDABOUT_M5 = Path(__file__).resolve().parents[1] / "results" / "paper-budget" / "M5" / "seed3" / "best.pt"
SO_FAR = re.compile(r"so far: (\d+) agent-agent .* (\d+) agent-lane .*\nthis step: (\d+) agent, (\d+) lane")


def _rows(steps: int) -> pd.DataFrame:
    actor, state = load_policy(ROUNDABOUT_M5, n_agents=scenario_of("Roundabout").n_agents, device="cpu")
    rows = evaluate_policy(actor, ckpt.config_of(state, ROUNDABOUT_M5), "Roundabout", n_sims=4, steps=steps,
                           seed=2024, progress=False)
    return (rows.set_index("simulation")[["CR_AA", "CR_AL"]] * steps).round().astype(int)


@pytest.mark.slow
def test_running_collision_counts_are_the_evaluation_rows_and_collisions_show_in_red(tmp_path):
    """A committed policy (M5 seed 3, which collides on the Roundabout) animated for simulations
    0 and 3 of a 4-simulation evaluation: each title's running counts are the rows of an
    evaluation of the same length, at step 60 and at the last step; a step with a contact
    has pure red pixels (the marked vehicles), a step without none."""
    films = animate(ROUNDABOUT_M5, "Roundabout", [0, 3], steps=150, n_sims=4, seed=2024, out_dir=tmp_path, mp4=False)
    counts = {k: [tuple(int(x) for x in SO_FAR.search(t).groups()) for t in film.titles] for k, film in films.items()}
    for t, rows in ((60, _rows(60)), (150, _rows(150))):
        for k in (0, 3):
            assert counts[k][t - 1][:2] == (rows.loc[k, "CR_AA"], rows.loc[k, "CR_AL"]), (k, t)
    assert sum(films[k].agent + films[k].lane for k in films) >= 2  # the check saw collisions
    for k, film in films.items():
        assert (film.agent, film.lane) == counts[k][-1][:2]
        assert film.files == [tmp_path / f"M5_seed3_Roundabout_sim{k}.gif"]
        gif = Image.open(film.files[0])
        assert gif.n_frames == 150
        for i, (_, _, now_agent, now_lane) in enumerate(counts[k]):
            gif.seek(i)
            rgb = np.asarray(gif.convert("RGB")).astype(int)
            red = ((rgb[..., 0] > 240) & (rgb[..., 1] < 20) & (rgb[..., 2] < 20)).sum()
            assert (red > 20) == (now_agent + now_lane > 0), (k, i, red)
