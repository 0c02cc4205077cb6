"""Evaluation rollouts: metrics worked out by hand for scripted policies, determinism, errors."""

from __future__ import annotations

import pytest
import torch

from sigmarl.compose import compose_config
from sigmarl.env import make_env
from sigmarl.errors import SigmarlError
from sigmarl.evaluation.rollout import evaluate_policy
from sigmarl.maps import scenario_map_config
from sigmarl.scenarios import scenario_names


def still(obs):
    return torch.zeros(*obs.shape[:-1], 2)


def forward(speed):
    def act(obs):
        a = torch.zeros(*obs.shape[:-1], 2)
        a[..., 0] = speed
        return a

    return act


@pytest.fixture(scope="module")
def cfg():
    return compose_config([])


@pytest.mark.parametrize("scenario", scenario_names())
def test_standing_still_scores_zero(cfg, scenario):
    # Vehicles spawn on their center line, at least 0.2147 m apart, inside their lane:
    # standing still they never collide, deviate or move.
    rows = evaluate_policy(still, cfg, scenario, n_sims=3, steps=20, progress=False)
    assert len(rows) == 3
    assert (rows[["CR_AA", "CR_AL", "CR_total", "AS"]] == 0).all().all()
    assert rows["CD"].max() < 1e-4  # cm: float32 rounding only


def test_constant_speed_gives_that_average_speed(cfg):
    # AS averages |v| over agent-steps; every agent (respawned ones too) drives at 0.5 m/s.
    rows = evaluate_policy(forward(0.5), cfg, "CPM", n_sims=2, steps=30, progress=False)
    assert rows["AS"].to_numpy() == pytest.approx(0.5, abs=1e-6)
    assert (rows["CR_total"] == rows["CR_AA"] + rows["CR_AL"]).all()
    assert (rows[["CR_AA", "CR_AL"]] <= 1).all().all()


def test_deterministic_given_seed(cfg):
    torch.manual_seed(0)
    w = torch.randn(cfg_obs_dim(cfg), 2) * 0.3

    def linear(obs):
        return torch.tanh(obs @ w) * torch.tensor([0.8, 0.6])

    a = evaluate_policy(linear, cfg, "Intersection", n_sims=2, steps=40, seed=7, progress=False)
    b = evaluate_policy(linear, cfg, "Intersection", n_sims=2, steps=40, seed=7, progress=False)
    assert a.equals(b)


OBS_DIMS = {"full": 32}  # M0's observation size, counted by hand


def cfg_obs_dim(cfg) -> int:
    if cfg.obs.preset not in OBS_DIMS:
        pytest.fail(f"no hand-counted observation size for obs={cfg.obs.preset}")
    return OBS_DIMS[cfg.obs.preset]


def test_all_models_face_the_same_initial_states(cfg):
    # Initial states depend on the evaluation seed only, not on the observation design.
    other = compose_config(["obs=no_ego_view"])
    m = scenario_map_config("Roundabout")
    pos = []
    for c in (cfg, other):
        env = make_env(c, num_envs=4, n_agents=8, mode="test", map_cfg=m, seed=11)
        env.reset()
        pos.append(env.scenario.pos.clone())
    assert torch.equal(pos[0], pos[1])


def test_policy_with_wrong_input_size_is_a_clear_error(cfg):
    net = torch.nn.Linear(50, 2)  # a policy trained with obs=no_distance_to_boundaries
    with pytest.raises(SigmarlError, match="cannot act on CPM's observations \\(size 32"):
        evaluate_policy(net, cfg, "CPM", n_sims=1, steps=2, progress=False)


def test_unknown_scenario(cfg):
    with pytest.raises(SigmarlError, match="unknown scenario"):
        evaluate_policy(still, cfg, "Highway", n_sims=1, steps=1, progress=False)
