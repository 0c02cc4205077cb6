"""Rendering: a state to PNG, a rollout to GIF, collisions drawn in red."""

from __future__ import annotations

import importlib.util
import io

import imageio.v3 as iio
import numpy as np
import pytest
import torch

from sigmarl.compose import compose_config
from sigmarl.env.factory import make_env
from sigmarl.env.render import render_rollout, render_state, scenario_of
from sigmarl.errors import SigmarlError


@pytest.fixture(scope="module")
def env():
    return make_env(compose_config(), num_envs=2, n_agents=4, seed=1)


def _place(env, behind: int):
    """Agents 0 and 1 on one route, agent 1 `behind` center points (0.08 m each) behind
    agent 0 (1: the rectangles overlap); agents 2 and 3 far away on other routes."""
    sc = scenario_of(env)
    route = torch.tensor([0, 0, 6, 12])
    idx = torch.tensor([10, 10 - behind, 10, 10])
    pos = sc.bank.center[route, idx].clone()
    sc.set_state(route, pos, sc.bank.heading[route, idx].clone())
    return sc, pos


def _pixels(fig) -> np.ndarray:
    fig.canvas.draw()
    return np.asarray(fig.canvas.buffer_rgba())[..., :3]


def _red_near(fig, points: torch.Tensor, radius: int = 14) -> int:
    """Pure-red pixels within `radius` pixels of each point (data coordinates)."""
    img = _pixels(fig)
    h = img.shape[0]
    red = (img[..., 0] > 200) & (img[..., 1] < 60) & (img[..., 2] < 60)
    ax = fig.axes[0]
    count = 0
    for x, y in ax.transData.transform(points.numpy()):
        r, c = int(round(h - y)), int(round(x))
        count += int(red[max(r - radius, 0) : r + radius, max(c - radius, 0) : c + radius].sum())
    return count


def test_state_renders_to_png_of_the_expected_size(env):
    env.reset()
    fig = render_state(env, figsize=(5.0, 4.0), dpi=80)
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    img = iio.imread(buf.getvalue(), extension=".png")
    assert img.shape[:2] == (320, 400)
    # Something besides the white background was drawn: the map and the vehicles.
    assert (img[..., :3] < 250).any(-1).mean() > 0.05
    assert "step" in fig.axes[0].get_title()


def test_rollout_writes_one_gif_frame_per_step(env, tmp_path):
    path = render_rollout(env, steps=10, path=tmp_path / "roll.gif")
    frames = iio.imread(path, index=None)
    assert frames.shape[0] == 10
    assert frames.shape[-1] in (3, 4) and frames.shape[1] > 100 and frames.shape[2] > 100


def test_rollout_with_a_policy_and_a_bad_suffix(env, tmp_path):
    calls = []

    def policy(td):
        calls.append(1)
        td[("agents", "action")] = env.full_action_spec[("agents", "action")].zero()
        return td

    render_rollout(env, policy=policy, steps=3, path=tmp_path / "p.gif")
    assert len(calls) == 3
    with pytest.raises(SigmarlError, match="gif"):
        render_rollout(env, steps=1, path=tmp_path / "roll.avi")


@pytest.mark.skipif(
    bool(importlib.util.find_spec("imageio_ffmpeg") or importlib.util.find_spec("av")),
    reason="an ffmpeg writer is installed",
)
def test_mp4_without_ffmpeg_suggests_gif(env, tmp_path):
    with pytest.raises(SigmarlError, match=r"\.gif"):
        render_rollout(env, steps=1, path=tmp_path / "roll.mp4")
    assert not (tmp_path / "roll.mp4").exists()


def test_colliding_pair_is_highlighted(env):
    sc, pos = _place(env, behind=1)
    assert sc.agent_collision[0].tolist() == [True, True, False, False]
    assert not sc.lane_collision[0].any()
    fig = render_state(env)
    edges = [p.get_edgecolor()[:3] for p in fig.axes[0].patches[-4:]]
    assert edges[:2] == [(1.0, 0.0, 0.0)] * 2 and edges[2:] != [(1.0, 0.0, 0.0)] * 2
    assert _red_near(fig, pos[:2]) > 20
    assert _red_near(fig, pos[2:]) == 0


def test_separate_vehicles_have_no_red(env):
    sc, pos = _place(env, behind=6)
    assert not (sc.agent_collision[0] | sc.lane_collision[0]).any()
    assert _red_near(render_state(env), pos) == 0


def test_a_scenario_renders_its_own_map_or_a_given_one(env, kit):
    sc = scenario_of(env)
    assert render_state(sc).axes[0].get_title().startswith(sc.road_map.name)
    other = kit.straight_road_map()
    assert render_state(sc, road_map=other).axes[0].get_title().startswith(other.name)
    # an evaluation's frames name what is shown, not only the map
    assert render_state(sc, title="On-Ramp · M2 seed 3").axes[0].get_title().startswith("On-Ramp · M2 seed 3 · ")


def test_test_mode_collision_is_drawn_where_it_happened():
    """In test mode colliders respawn within the step; the frame of that step shows them red at
    the pose they collided in, not at their new start."""
    env = make_env(compose_config(), num_envs=2, n_agents=4, seed=1, mode="test")
    td = env.reset()
    sc, pos = _place(env, behind=1)
    td["agents", "action"] = torch.zeros(2, 4, 2)
    nxt = env.step(td)["next"]
    hit = nxt["agents", "info", "agent_collision"][0].squeeze(-1).bool()
    assert hit.tolist() == [True, True, False, False]
    assert nxt["agents", "info", "respawned"][0, :2].bool().all()
    assert (sc.pos[0, :2] - pos[:2]).norm(dim=-1).min() > 0.05  # they did respawn elsewhere
    fig = render_state(env)
    edges = [p.get_edgecolor()[:3] for p in fig.axes[0].patches[-4:]]
    assert edges[:2] == [(1.0, 0.0, 0.0)] * 2
    assert _red_near(fig, pos[:2]) > 20
    assert _red_near(fig, sc.pos[0, :2]) == 0
