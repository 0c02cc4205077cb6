"""Episodes, resets and initial states, bad input, determinism.

Straight road of conftest: center line y = 0 (points every 0.08 m at x = 0.08 k, last real
point x = 4.00, then the straight extension), boundaries y = +-0.075.
"""

from __future__ import annotations

import itertools
import math

import pytest
import torch

from sigmarl.compose import compose_config
from sigmarl.env.factory import make_env
from sigmarl.env.reward import total_reward
from sigmarl.errors import SigmarlError

MIN_GAP = 1.2 * math.hypot(0.16, 0.08)  # 1.2 x vehicle diagonal = 0.214663 m


def info(nxt, key):
    return nxt["agents", "info", key].squeeze(-1)


def min_gap_to_others(pos: torch.Tensor) -> torch.Tensor:
    """[E, A] distance from each agent to its nearest other agent."""
    d = torch.cdist(pos.double(), pos.double())
    d = d + torch.eye(pos.shape[1], dtype=d.dtype) * 1e9
    return d.min(-1).values


# ---------------------------------------------------------------- training mode
def test_train_collision_ends_that_envs_episode(env_factory, straight_road):
    """env 0: agent-agent overlap; env 1: agent 0 crosses the left boundary (corners at
    y = 0.08); env 2: nothing. A standing-still step terminates envs 0 and 1 only (not a
    truncation); torchrl's step_and_maybe_reset then respawns every agent of those envs and
    leaves env 2 alone."""
    drv = env_factory(road_map=straight_road, num_envs=3, n_agents=2, mode="train")
    pos = torch.tensor([[[1.0, 0.0], [1.1, 0.0]], [[1.0, 0.04], [3.0, 0.0]], [[1.0, 0.0], [3.0, 0.0]]])
    drv.place(pos, torch.zeros(3, 2))
    drv.td["agents", "action"] = torch.zeros(3, 2, 2)
    out, root = drv.env.step_and_maybe_reset(drv.td)
    nxt = out["next"]
    assert nxt["terminated"].flatten().tolist() == [True, True, False]
    assert nxt["done"].flatten().tolist() == [True, True, False]
    assert nxt["truncated"].flatten().tolist() == [False, False, False]
    assert info(nxt, "agent_collision").tolist() == [[1, 1], [0, 0], [0, 0]]
    assert info(nxt, "lane_collision").tolist() == [[0, 0], [1, 0], [0, 0]]
    sc = drv.sc
    # the terminal step keeps its reward through the reset that follows it, collision
    # penalties included (a reset once zeroed them in the returned step)
    reward = nxt["agents", "reward"].squeeze(-1)
    torch.testing.assert_close(reward, total_reward(sc.terms))
    assert (reward[0] <= -0.5).all() and reward[1, 0] <= -0.5, reward
    # env 2 untouched, envs 0 and 1 fully respawned (all agents of the env; none of the
    # old positions x = 1.0, 1.1, 3.0 is a training spawn point 0.08 k in [0.56, 2.0])
    torch.testing.assert_close(sc.pos[2], pos[2])
    for e in (0, 1):
        for a in range(2):
            assert not torch.allclose(sc.pos[e, a], pos[e, a]), (e, a)
    assert root["step_count"].flatten().tolist() == [0, 0, 1]
    assert not root["terminated"].any()
    # respawned agents sit on the center line, within the route, apart from each other
    assert sc.pos[..., 1].abs().max() < 1e-6
    assert ((sc.pos[..., 0] >= 0.25) & (sc.pos[..., 0] <= 3.75)).all()
    assert (min_gap_to_others(sc.pos) >= MIN_GAP - 1e-6).all()


def test_train_timeout_is_a_truncation_at_128_steps(env_factory, straight_road):
    """Standing still (speed 0) on the center line, spaced >= 0.2147 m apart: no collision
    ever; the episode ends at step 128 (env.max_steps default) with truncated True and
    terminated False."""
    drv = env_factory(road_map=straight_road, num_envs=2, n_agents=2, mode="train")
    assert drv.sc.train

    def zero(td):
        td["agents", "action"] = torch.zeros(2, 2, 2)
        return td

    roll = drv.env.rollout(130, policy=zero, break_when_any_done=False)
    trunc = roll["next", "truncated"].squeeze(-1)  # [E, T]
    term = roll["next", "terminated"].squeeze(-1)
    done = roll["next", "done"].squeeze(-1)
    assert not term.any()
    assert not trunc[:, :127].any()
    assert trunc[:, 127].all() and done[:, 127].all()
    assert roll["next", "step_count"][:, 127].flatten().tolist() == [128, 128]
    # after the automatic reset a new episode counts again from 1
    assert roll["next", "step_count"][:, 128].flatten().tolist() == [1, 1]


def test_train_exit_respawns_that_agent_alone(env_factory, straight_road):
    """Agent 0 at x = 3.99 drives 0.8 m/s: after the step it is at 4.03, past the last real
    point x = 4.00 (closest point 4.00, 0.03 m; 4.08 is 0.05 m) -> it respawns; agent 1
    standing at x = 1.0 keeps its state; nothing terminates."""
    drv = env_factory(road_map=straight_road, num_envs=1, n_agents=2, mode="train")
    drv.place(torch.tensor([[3.99, 0.0], [1.0, 0.0]]), torch.zeros(2), speed=torch.tensor([0.8, 0.0]))
    nxt = drv.step(torch.tensor([[0.8, 0.0], [0.0, 0.0]]))
    assert not nxt["done"].any()
    assert info(nxt, "respawned")[0].tolist() == [1, 0]
    assert drv.sc.pos[0, 1].tolist() == pytest.approx([1.0, 0.0], abs=1e-6)
    assert drv.sc.pos[0, 0, 0].item() <= 3.75
    assert (min_gap_to_others(drv.sc.pos) >= MIN_GAP - 1e-6).all()


# ---------------------------------------------------------------- test mode
def expected_obs_on_center_line(pos: torch.Tensor, speed: torch.Tensor) -> list[list[torch.Tensor]]:
    """Full-preset observations of agents standing on y = 0 with heading 0 (straight road),
    by hand: closest center point k = round(x / 0.08); look-ahead points at (k + 2, 4, 6) *
    0.08, ego (dx, 0) / 1.6; DC |y| / 0.45 = 0; DB (0.075 - 0.04) / 0.45 both sides; the two
    nearest others: corners (xj +- 0.08 - xi, +-0.04) / 1.6, velocity (vj, 0) / 0.8, distance
    |xj - xi| / 0.45. Per agent, one candidate row per admissible neighbour order (equal
    distances, e.g. 0.72 on both sides, may come in either order)."""
    x = pos[:, 0].tolist()
    v = speed.tolist()
    rows = []
    for i, xi in enumerate(x):
        k = round(xi / 0.08)
        own = [v[i] / 0.8]
        for m in (2, 4, 6):
            own += [((k + m) * 0.08 - xi) / 1.6, 0.0]
        own += [0.0, 0.035 / 0.45, 0.035 / 0.45]
        others = [j for j in range(len(x)) if j != i]
        orders = set()
        for perm in itertools.permutations(others):
            d = [abs(x[j] - xi) for j in perm]
            if all(d[n] <= d[n + 1] + 1e-6 for n in range(len(d) - 1)):
                orders.add(perm[:2])
        cands = []
        for order in sorted(orders):
            o = list(own)
            for j in order:
                xj = x[j]
                for cx, cy in ((0.08, 0.04), (0.08, -0.04), (-0.08, -0.04), (-0.08, 0.04)):
                    o += [(xj + cx - xi) / 1.6, cy / 1.6]
                o += [v[j] / 0.8, 0.0, abs(xj - xi) / 0.45]
            cands.append(torch.tensor(o))
        rows.append(cands)
    return rows


def test_test_mode_respawns_only_colliders_and_exited(env_factory, straight_road):
    """Test mode, 5 agents, 4 envs with the same scene:
    A0 (1.0, 0) and A1 (1.1, 0) overlap; A2 at x = 3.99 drives out past x = 4.00;
    A3 at x = 2.5 drives 0.8 m/s (-> 2.54) untouched; A4 at (1.8, 0.04) touches the left
    boundary. After one step: A0, A1, A2, A4 respawn, A3 keeps its state; nothing
    terminates; respawned agents are >= 0.2147 m from every other agent; the observation
    returned is the one of the new state."""
    n_env = 4
    drv = env_factory(["obs=full"], road_map=straight_road, num_envs=n_env, n_agents=5, mode="test")
    assert not drv.sc.train
    pos = torch.tensor([[1.0, 0.0], [1.1, 0.0], [3.99, 0.0], [2.5, 0.0], [1.8, 0.04]])
    speed = torch.tensor([0.0, 0.0, 0.8, 0.8, 0.0])
    drv.place(pos, torch.zeros(5), speed=speed)
    action = torch.tensor([[0.0, 0.0], [0.0, 0.0], [0.8, 0.0], [0.8, 0.0], [0.0, 0.0]])
    nxt = drv.step(action)
    sc = drv.sc
    assert not nxt["done"].any() and not nxt["terminated"].any()
    for e in range(n_env):
        assert info(nxt, "agent_collision")[e].tolist() == [1, 1, 0, 0, 0]
        assert info(nxt, "lane_collision")[e].tolist() == [0, 0, 0, 0, 1]
        assert info(nxt, "respawned")[e].tolist() == [1, 1, 1, 0, 1]
    # A3 kept its state: 2.5 + 0.8 * 0.05 = 2.54, heading 0, speed 0.8
    assert sc.pos[:, 3].flatten().tolist() == pytest.approx([2.54, 0.0] * n_env, abs=1e-5)
    assert sc.speed[:, 3].tolist() == pytest.approx([0.8] * n_env, abs=1e-6)
    assert sc.heading[:, 3].abs().max() < 1e-6
    # The others got new states on the center line, inside the test-mode range [0.25, 3.75].
    moved = [0, 1, 2, 4]
    assert sc.pos[:, moved, 1].abs().max() < 1e-6
    assert ((sc.pos[:, moved, 0] >= 0.25 - 1e-6) & (sc.pos[:, moved, 0] <= 3.75 + 1e-6)).all()
    assert sc.heading[:, moved].abs().max() < 1e-6
    assert ((sc.speed[:, moved] >= 0) & (sc.speed[:, moved] < 0.8)).all()
    assert (min_gap_to_others(sc.pos) >= MIN_GAP - 1e-6).all()
    # The returned observation describes the new state (noise 0).
    obs = nxt["agents", "observation"]
    for e in range(n_env):
        for a, cands in enumerate(expected_obs_on_center_line(sc.pos[e], sc.speed[e])):
            assert any(torch.allclose(obs[e, a], c, atol=2e-5, rtol=0) for c in cands), (e, a, obs[e, a], cands)


def test_respawns_keep_the_minimum_gap_in_random_rollouts(kit):
    """CPM intersection, test mode, 6 agents, random actions (seeded generator): at the first
    reset and after every step, every respawned agent is >= 0.2147 m from all others."""
    cfg = kit.cfg(("obs.noise=0", "map=cpm_intersection"))
    env = make_env(cfg, num_envs=6, n_agents=6, mode="test")
    sc = env.scenario
    td = env.reset()
    assert (min_gap_to_others(sc.pos) >= MIN_GAP - 1e-6).all()
    gen = torch.Generator().manual_seed(5)
    hi = torch.tensor([0.8, math.radians(35)])
    n_respawned = 0
    for _ in range(60):
        td["agents", "action"] = (torch.rand(6, 6, 2, generator=gen) * 2 - 1) * hi
        td = env.step(td)["next"]
        r = info(td, "respawned").bool()
        n_respawned += int(r.sum())
        gap = min_gap_to_others(sc.pos)
        assert (gap[r] >= MIN_GAP - 1e-6).all(), gap[r]
    assert n_respawned > 10  # the check was exercised


@pytest.mark.parametrize(("map_name", "mode", "n_agents"), [("cpm_intersection", "train", 4), ("cpm", "test", 10)])
def test_observation_after_resets_equals_one_computed_from_scratch(kit, map_name, mode, n_agents):
    """Respawned agents take their geometry from a per-spawn-point table instead of a second
    geometry pass: after every step (partial resets, respawns) and after a full reset that
    follows a history, the observation must equal the one recomputed from the state."""
    cfg = kit.cfg(("obs.noise=0", f"map={map_name}"))
    env = make_env(cfg, num_envs=6, n_agents=n_agents, mode=mode)
    sc = env.scenario
    td = env.reset()
    gen = torch.Generator().manual_seed(3)
    hi = torch.tensor([0.8, math.radians(35)])
    n_reset = 0

    def check(obs):
        sc._geometry()
        sc._observe()
        torch.testing.assert_close(obs, sc.obs, atol=1e-5, rtol=0)

    for _ in range(40):
        td["agents", "action"] = (torch.rand(6, n_agents, 2, generator=gen) * 2 - 1) * hi
        out, td = env.step_and_maybe_reset(td)
        n_reset += int(out["next", "done"].sum() + info(out["next"], "respawned").sum())
        check(td["agents", "observation"])
    env.set_seed(11)
    check(env.reset()["agents", "observation"])
    assert n_reset > 5  # resets and respawns were exercised


# ---------------------------------------------------------------- bad input
def test_more_agents_than_the_map_holds_fails_before_stepping(kit, straight_road):
    """Training spawns on the 4 m straight road lie on x in [0.56, 2.0]: at most
    1.44 / 0.2147 + 1 = 7 agents fit; 12 cannot. The CPM intersection cannot hold 60."""
    cfg = kit.cfg(("obs.noise=0",))
    with pytest.raises(SigmarlError, match="12 agents"):
        env = make_env(cfg, road_map=straight_road, num_envs=1, n_agents=12)
        env.reset()
    with pytest.raises(SigmarlError, match="60 agents"):
        env = make_env(cfg, num_envs=1, n_agents=60)
        env.reset()


def test_too_many_agents_message_counts_agents_of_one_environment(kit, straight_road):
    """The message 'could not place N agent(s) ... cannot hold 12 agents' must not claim
    more unplaced agents than were requested (it summed over environments)."""
    cfg = kit.cfg(("obs.noise=0",))
    with pytest.raises(SigmarlError) as err:
        make_env(cfg, road_map=straight_road, num_envs=4, n_agents=12).reset()
    n = int(str(err.value).split("could not place ")[1].split(" ")[0])
    assert 1 <= n <= 12, str(err.value)


def test_negative_noise_is_rejected(kit):
    with pytest.raises(SigmarlError, match="noise"):
        make_env(kit.cfg(("obs.noise=-0.01",)), num_envs=1)


@pytest.mark.parametrize("override", ["obs.ego_veiw=false", "obs.no_such_flag=true", "obs=no_such_preset"])
def test_unknown_observation_flag_is_a_config_error(override):
    with pytest.raises(SigmarlError):
        compose_config([override])


def test_appended_unknown_observation_flag_is_rejected():
    """Hydra's own error for `obs.ego_veiw=false` tells the user to write `+obs.ego_veiw=false`;
    that composes (Hydra's `+` opens the struct), so the misspelt flag must still be rejected
    before any stepping, instead of silently training the full model."""
    with pytest.raises(SigmarlError):
        cfg = compose_config(["+obs.ego_veiw=false"])
        make_env(cfg, num_envs=1)


# ---------------------------------------------------------------- determinism
def _trajectory(cfg, seed, steps=25):
    env = make_env(cfg, num_envs=3, seed=seed)
    gen = torch.Generator().manual_seed(11)
    hi = torch.tensor([0.8, math.radians(35)])
    td = env.reset()
    obs, rew, done = [td["agents", "observation"].clone()], [], []
    for _ in range(steps):
        td["agents", "action"] = (torch.rand(3, 4, 2, generator=gen) * 2 - 1) * hi
        out, td = env.step_and_maybe_reset(td)
        obs.append(out["next", "agents", "observation"].clone())
        rew.append(out["next", "agents", "reward"].clone())
        done.append(out["next", "done"].clone())
    return torch.stack(obs), torch.stack(rew), torch.stack(done)


def test_same_seed_same_trajectory(kit):
    """Noise on (0.02), random actions from a seeded generator, resets included."""
    cfg = kit.cfg(("obs.noise=0.02", "map=cpm_intersection", "env.n_agents=4"))
    a, b = _trajectory(cfg, 3), _trajectory(cfg, 3)
    for x, y in zip(a, b, strict=True):
        assert torch.equal(x, y)


def test_different_seed_gives_different_initial_states(kit):
    cfg = kit.cfg(("obs.noise=0", "map=cpm_intersection", "env.n_agents=4"))
    pos = []
    for seed in (0, 1):
        env = make_env(cfg, num_envs=3, seed=seed)
        env.reset()
        pos.append(env.scenario.pos.clone())
    assert not torch.allclose(pos[0], pos[1])


def test_initial_states_do_not_depend_on_the_observation_design(kit):
    """Every model of the ablation must face the same initial states for a seed: the noise draws
    (which differ in number between presets: 32 vs 50 entries) must not shift the spawns."""
    pos = []
    for preset in ("full", "no_distance_to_boundaries"):
        cfg = kit.cfg((f"obs={preset}", "obs.noise=0.02", "map=cpm_intersection"))
        env = make_env(cfg, num_envs=3, n_agents=4, seed=2)
        td = env.reset()
        td["agents", "action"] = torch.zeros(3, 4, 2)
        for _ in range(3):
            td = env.step(td)["next"]
            td["agents", "action"] = torch.zeros(3, 4, 2)
        env.reset()
        pos.append(env.scenario.pos.clone())
    torch.testing.assert_close(pos[0], pos[1])
