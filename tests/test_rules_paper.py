"""The paper's own rules (`rules.*`), one switch at a time, each against numbers worked by hand.

Scenes use the straight road of conftest (center line y = 0, boundaries y = +-0.075; its raw
map vertices every 0.2 m: x = 0, 0.2, ..., 4.0, then the raw extension 4.1 .. 4.8) unless a
test builds its own map. Vehicles are 0.16 m x 0.08 m, wheelbase 0.16 m, l_r 0.08 m, dt 0.05 s.

Observation layout of M0 (ego view, K = 2): [0] own speed, [1:7] reference points, [7] DC,
[8] DB left, [9] DB right, then per other: [10:18] corners, [18:20] velocity, [20] distance.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import torch
import yaml

from sigmarl.compose import compose_config, conf_dir
from sigmarl.config import Config, RulesConfig
from sigmarl.env.paper_rules import (
    MEASUREMENT_SWITCHES,
    densify,
    for_evaluation,
    rules_label,
    switches_on,
)
from sigmarl.evaluation.protocol import rows_rules
from sigmarl.identity import fingerprint
from sigmarl.maps.model import Lanelet, RoadMap
from sigmarl.maps.routes import build_route
from sigmarl.readers import read_run_config

STEER_FREE, STEER_SCALE = math.radians(10), math.radians(50)
ALL = [f.name for f in dataclasses.fields(RulesConfig)]


def _beta(delta: float) -> float:
    return math.atan(0.5 * math.tan(delta))


def _yaw_rate(v: float, delta: float) -> float:
    """psi' of the kinematic model: (v / L) cos(beta) tan(delta), L = 0.16 m."""
    return v / 0.16 * math.cos(_beta(delta)) * math.tan(delta)


# ---- the config group ----------------------------------------------------------------------
def test_every_switch_is_a_config_key_and_the_presets_turn_all_off_or_on(kit):
    assert kit.cfg(()).rules == RulesConfig()  # rules=ours is the default: every switch off
    assert all(getattr(kit.cfg(("rules=paper",)).rules, k) for k in ALL)
    one = kit.cfg(("rules.timeout_terminal=true",)).rules
    assert switches_on(one) == ["timeout_terminal"]
    paper = yaml.safe_load((conf_dir() / "rules" / "paper.yaml").read_text())
    assert sorted(k for k in paper if k != "defaults") == sorted(ALL)


def test_rules_label_and_what_evaluation_keeps():
    assert rules_label(RulesConfig()) == "ours"
    assert rules_label(RulesConfig(**dict.fromkeys(ALL, True))) == "paper"
    assert rules_label(RulesConfig(drag_dynamics=True, lagged_steering=True)) == "drag_dynamics+lagged_steering"
    before_reward = RulesConfig(**{**dict.fromkeys(ALL, True), "reward_normaliser_one": False, "reset_speed_one": False})
    assert rules_label(before_reward) == "paper-reward_normaliser_one+reset_speed_one"
    cfg = for_evaluation(Config(rules=RulesConfig(**dict.fromkeys(ALL, True))))
    # evaluation measures our way: contacts, per-agent flags, fresh observations ...
    assert not any(getattr(cfg.rules, k) for k in MEASUREMENT_SWITCHES)
    # ... under the dynamics and observation the policy was trained with
    assert all(getattr(cfg.rules, k) for k in ALL if k not in MEASUREMENT_SWITCHES)


def test_resuming_under_other_rules_is_a_config_change():
    from sigmarl.config import as_dict
    from sigmarl.training.loop import config_changes

    saved = as_dict(Config())
    del saved["rules"]  # a checkpoint from before the rules existed: ours
    assert config_changes(saved, Config()) == []
    assert config_changes(saved, Config(rules=RulesConfig(drag_dynamics=True))) == ["rules.drag_dynamics"]


def test_rows_without_a_rules_column_mean_ours():
    old = pd.DataFrame({"model": ["M0", "M0"], "CR_AA": [0.0, 0.1]})
    assert rows_rules(old).tolist() == ["ours", "ours"]
    new = old.assign(rules="paper")
    assert rows_rules(pd.concat([old, new], ignore_index=True)).tolist() == ["ours", "ours", "paper", "paper"]


# ---- 1. dynamics ---------------------------------------------------------------------------
def test_drag_dynamics_step_response_alternates_to_0_8_of_the_command(env_factory, wide_road):
    """v_k = c - 0.25 v_{k-1} from rest: c, 0.75 c, 0.8125 c, 0.796875 c, ... -> 0.8 c."""
    d = env_factory(["rules.drag_dynamics=true"], num_envs=1, n_agents=1, road_map=wide_road)
    d.place([[1.0, 0.0]], [0.0], speed=[0.0])
    c, v, x = 0.5, 0.0, 1.0
    for _ in range(6):
        info = d.step([c, 0.0])["agents", "info"]
        v = c - 0.25 * v
        x += v * 0.05
        assert float(info["speed"].squeeze()) == pytest.approx(v, abs=1e-6)
        assert float(d.sc.pos[0, 0, 0]) == pytest.approx(x, abs=1e-6)
    assert [c, 0.75 * c, 0.8125 * c][2] == pytest.approx(0.40625)
    for _ in range(30):
        d.step([1.0, 0.0])  # the command's range is [-1, 1]: top speed 0.8 m/s
    assert float(d.sc.speed[0, 0]) == pytest.approx(0.8, abs=1e-5)
    assert d.env.full_action_spec["agents", "action"].space.high[0, 0, 0] == pytest.approx(1.0)


def test_drag_dynamics_yaw_rate_alternates_like_the_speed_and_keeps_the_turning_radius(env_factory, wide_road):
    """psi'_k = w - 0.25 psi'_{k-1} with w the kinematic yaw rate of the command; in the steady
    state v = 0.8 c and psi' = 0.8 w, so the radius v / psi' is the kinematic one."""
    d = env_factory(["rules.drag_dynamics=true", "rules.unwrapped_headings=true"], num_envs=1, n_agents=1,
                    road_map=wide_road)
    d.place([[2.0, 0.0]], [0.0], speed=[0.0])
    c, delta = 0.4, 0.3
    w, rate, heading = _yaw_rate(c, delta), 0.0, 0.0
    for _ in range(4):
        d.step([c, delta])
        rate = w - 0.25 * rate
        heading += rate * 0.05
        assert float(d.sc.heading[0, 0]) == pytest.approx(heading, abs=1e-5)
    assert rate == pytest.approx(w * (1 - 0.25 + 0.0625 - 0.015625))
    for _ in range(40):
        d.step([c, delta])
    assert float(d.sc.yaw_rate[0, 0]) == pytest.approx(0.8 * w, rel=1e-4)
    radius = float(d.sc.speed[0, 0] / d.sc.yaw_rate[0, 0])
    assert radius == pytest.approx(c / w, rel=1e-4)  # = 0.16 / (cos(beta) tan(delta))


# ---- 2-4. speeds in the observation --------------------------------------------------------
def test_speed_normaliser_one(env_factory, straight_road):
    ours = env_factory([], num_envs=1, n_agents=1, road_map=straight_road).place([[1.0, 0.0]], [0.0], speed=[0.4])
    paper = env_factory(["rules.speed_normaliser_one=true"], num_envs=1, n_agents=1, road_map=straight_road)
    obs = paper.place([[1.0, 0.0]], [0.0], speed=[0.4])
    assert float(ours[0, 0, 0]) == pytest.approx(0.5)  # 0.4 / 0.8
    assert float(obs[0, 0, 0]) == pytest.approx(0.4)  # 0.4 / 1.0
    m1 = env_factory(["obs=no_ego_view", "rules.speed_normaliser_one=true"], num_envs=1, n_agents=1,
                     road_map=straight_road).place([[1.0, 0.0]], [0.0], speed=[0.4])
    assert m1[0, 0, 3:5].tolist() == pytest.approx([0.4, 0.0])  # (vx, vy) / 1.0 after x, y, heading


def test_unsigned_own_speed_when_reversing(env_factory, straight_road):
    ours = env_factory([], num_envs=1, n_agents=1, road_map=straight_road).place([[1.0, 0.0]], [0.0], speed=[-0.3])
    obs = env_factory(["rules.unsigned_speed=true"], num_envs=1, n_agents=1,
                      road_map=straight_road).place([[1.0, 0.0]], [0.0], speed=[-0.3])
    assert float(ours[0, 0, 0]) == pytest.approx(-0.375)
    assert float(obs[0, 0, 0]) == pytest.approx(0.375)  # |v| / 0.8


def test_others_velocity_along_their_heading_and_unsigned(env_factory, wide_road):
    """Agent 1 turns with delta = 0.3 at 0.4 m/s for one step: heading psi = w dt, course
    psi + beta. Ours observes 0.4 (cos, sin)(psi + beta) / 0.8, the paper 0.4 (cos, sin)(psi) / 0.8."""
    def make(rules):
        d = env_factory(rules, num_envs=1, n_agents=2, road_map=wide_road)
        d.place([[1.0, 0.0], [1.5, 0.3]], [0.0, 0.0], speed=[0.0, 0.0])
        d.step([[0.0, 0.0], [0.4, 0.3]])
        return d.td["agents", "observation"][0, 0, 18:20]
    psi = _yaw_rate(0.4, 0.3) * 0.05
    course = psi + _beta(0.3)
    assert make([]).tolist() == pytest.approx([0.5 * math.cos(course), 0.5 * math.sin(course)], abs=1e-5)
    assert make(["rules.others_velocity_heading=true"]).tolist() == pytest.approx(
        [0.5 * math.cos(psi), 0.5 * math.sin(psi)], abs=1e-5)
    # reversing: the paper's is unsigned, along the heading
    rev = env_factory(["rules.others_velocity_heading=true"], num_envs=1, n_agents=2, road_map=wide_road)
    obs = rev.place([[1.0, 0.0], [1.5, 0.3]], [0.0, 0.0], speed=[0.0, -0.4])
    assert obs[0, 0, 18:20].tolist() == pytest.approx([0.5, 0.0])
    ours = env_factory([], num_envs=1, n_agents=2, road_map=wide_road)
    assert ours.place([[1.0, 0.0], [1.5, 0.3]], [0.0, 0.0], speed=[0.0, -0.4])[0, 0, 18:20].tolist() == \
        pytest.approx([-0.5, 0.0])


# ---- 5. unwrapped headings -----------------------------------------------------------------
def test_unwrapped_own_heading_passes_pi(env_factory, wide_road):
    """From heading 3.4 at 0.8 m/s and 35 deg, one step turns w dt = 0.16520 rad: 3.56520, which
    ours wraps to 3.56520 - 2 pi = -2.71799 and the paper keeps."""
    delta = math.radians(35)
    new = 3.4 + _yaw_rate(0.8, delta) * 0.05
    assert new == pytest.approx(3.5652, abs=1e-4)
    for rules, expect in (([], new - 2 * math.pi), (["rules.unwrapped_headings=true"], new)):
        d = env_factory(["obs=no_ego_view", *rules], num_envs=1, n_agents=1, road_map=wide_road)
        d.place([[2.0, 0.0]], [3.4], speed=[0.8])
        d.step([0.8, delta])
        assert float(d.sc.heading[0, 0]) == pytest.approx(expect, abs=1e-5)
        assert float(d.td["agents", "observation"][0, 0, 2]) == pytest.approx(expect / (2 * math.pi), abs=1e-6)


def test_unwrapped_relative_heading(env_factory, wide_road):
    """M2 (ego view) observes another's heading relative to its own: 3.5 - (-3.0) = 6.5 rad;
    ours wraps it to 6.5 - 2 pi = 0.21681. Index: 10 self values, then the other's x, y, heading."""
    for rules, rel in (([], 6.5 - 2 * math.pi), (["rules.unwrapped_headings=true"], 6.5)):
        d = env_factory(["obs=no_vertices", *rules], num_envs=1, n_agents=2, road_map=wide_road)
        obs = d.place([[1.0, 0.0], [1.4, 0.0]], [-3.0, 3.5])
        assert float(obs[0, 0, 12]) == pytest.approx(rel / (2 * math.pi), abs=1e-6)


# ---- 6. one-sided noise --------------------------------------------------------------------
def test_one_sided_noise_has_mean_0_01_and_is_never_negative(env_factory, straight_road):
    """+ 0.02 U[0, 1) on every entry: in [0, 0.02), mean 0.01 (standard error of the mean over
    64 x 4 x 32 draws: 0.02 / sqrt(12 * 8192) = 6.4e-5). Ours: zero-mean in [-0.01, 0.01)."""
    pos = [[0.5, 0.0], [1.5, 0.0], [2.5, 0.0], [3.5, 0.0]]
    clean = env_factory([], num_envs=64, n_agents=4, road_map=straight_road).place(pos, [0.0] * 4)
    for rules, lo, mean in ((["rules.one_sided_noise=true"], 0.0, 0.01), ([], -0.01, 0.0)):
        d = env_factory(["obs.noise=0.02", *rules], num_envs=64, n_agents=4, road_map=straight_road)
        noise = d.place(pos, [0.0] * 4) - clean
        assert float(noise.min()) >= lo - 1e-6 and float(noise.max()) < lo + 0.02 + 1e-6
        assert float(noise.mean()) == pytest.approx(mean, abs=4e-4)


# ---- 7. raw center line --------------------------------------------------------------------
def corner_map() -> RoadMap:
    """A 90-degree left corner, lane 0.2 m wide: center (0.2k, 0) k = 0..5, then (1, 0.2k)
    k = 1..5; its left (inner) boundary 0.1 m inside, its right 0.1 m outside."""
    center = [(0.2 * k, 0.0) for k in range(6)] + [(1.0, 0.2 * k) for k in range(1, 6)]
    left = [(0.2 * k, 0.1) for k in range(5)] + [(0.9, 0.1)] + [(0.9, 0.2 * k) for k in range(1, 6)]
    right = [(0.2 * k, -0.1) for k in range(5)] + [(1.1, -0.1)] + [(1.1, 0.2 * k) for k in range(1, 6)]
    la = Lanelet(1, left=np.array(left), right=np.array(right))
    assert np.allclose(la.center, center)
    return RoadMap("corner", {1: la}, [build_route("corner", [1], {1: la})], lane_width=0.2, source="tests")


def test_raw_center_line_reference_points_are_raw_vertices(env_factory, straight_road):
    """Agent at (1.01, 0.01): its closest raw segment is [1.0, 1.2] (vertex 5), so the paper's
    reference points are vertices 7, 9, 11: x = 1.4, 1.8, 2.2 (ours: resampled 1.20, 1.36, 1.52);
    ego frame / 1.6."""
    for rules, xs in (([], [1.20, 1.36, 1.52]), (["rules.raw_center_line=true"], [1.4, 1.8, 2.2])):
        d = env_factory(rules, num_envs=1, n_agents=1, road_map=straight_road)
        obs = d.place([[1.01, 0.01]], [0.0])
        expect = [v for x in xs for v in ((x - 1.01) / 1.6, -0.01 / 1.6)]
        assert obs[0, 0, 1:7].tolist() == pytest.approx(expect, abs=1e-6)


def test_raw_center_line_distance_and_progress_on_the_raw_polyline(env_factory):
    """At the corner, outside it at (1.02, -0.02): the raw polyline's nearest point is the
    corner vertex (1, 0), 0.028284 m away; our resampled line cuts the corner with the chord
    (0.96, 0) -> (1, 0.04), 0.08 / sqrt 2 = 0.056569 m away. The paper observes (DC / 0.45) and
    is rewarded (deviation -0.02 d / 0.035) on the raw distance; the metric stays ours."""
    road = corner_map()
    for rules, dist in (([], 0.08 / math.sqrt(2)), (["rules.raw_center_line=true"], math.hypot(0.02, 0.02))):
        d = env_factory(["rules.strict_crossings=true", *rules], num_envs=1, n_agents=1, road_map=road,
                        mode="test")
        obs = d.place([[1.02, -0.02]], [math.pi / 4])
        assert float(obs[0, 0, 7]) == pytest.approx(dist / 0.45, abs=1e-5)
        nxt = d.step([0.0, 0.0])
        assert float(d.sc.terms["center_line_deviation"][0, 0]) == pytest.approx(-0.02 * dist / 0.035, abs=1e-5)
        metric = float(nxt["agents", "info", "distance_to_center_line"].squeeze())
        assert metric == pytest.approx(0.08 / math.sqrt(2), abs=1e-5)  # always ours


def test_raw_center_line_progress_reward_measures_against_raw_reference_points(env_factory, straight_road):
    """Driving 0.4 m/s straight from (1.01, 0): progress 0.1 sum_k w_k <step, r_k> / (0.8 dt),
    r_k from the reference points observed before the step (x = 1.4, 1.8, 2.2 raw)."""
    d = env_factory(["rules.raw_center_line=true"], num_envs=1, n_agents=1, road_map=straight_road)
    d.place([[1.01, 0.0]], [0.0], speed=[0.4])
    d.step([0.4, 0.0])
    w = [1 / 1.8, 0.6 / 1.8, 0.2 / 1.8]
    r = [1.4 - 1.01, 1.8 - 1.01, 2.2 - 1.01]
    expect = 0.1 * sum(wk * 0.02 * rk for wk, rk in zip(w, r, strict=True)) / (0.8 * 0.05)
    assert float(d.sc.terms["progress"][0, 0]) == pytest.approx(expect, abs=1e-5)


def test_reward_normaliser_one_divides_the_motion_terms_by_one(env_factory, straight_road):
    """The same step as above, raw reference points at x = 1.4, 1.8, 2.2 (r = 0.39, 0.79, 1.19 m
    from the ego before the step), velocity 0.4 m/s along x. Ours divides by 0.8 m/s, the
    paper's code by 1.0: progress 0.1 sum_k w_k 0.02 r_k / (s dt), speed 0.05 v_bar / s with
    v_bar = mean_k 0.4 r_k = 0.316, moving 0.05 * 0.4 / s; the penalties stay as they are."""
    w = [1 / 1.8, 0.6 / 1.8, 0.2 / 1.8]
    r = [0.39, 0.79, 1.19]
    got = {}
    for scale, extra in ((0.8, []), (1.0, ["rules.reward_normaliser_one=true"])):
        d = env_factory(["rules.raw_center_line=true", *extra], num_envs=1, n_agents=1, road_map=straight_road)
        d.place([[1.01, 0.0]], [0.0], speed=[0.4])
        d.step([0.4, 0.0])
        terms = {k: float(v[0, 0]) for k, v in d.sc.terms.items()}
        assert terms["progress"] == pytest.approx(0.1 * sum(a * 0.02 * b for a, b in zip(w, r, strict=True)) / (scale * 0.05), abs=1e-5)
        assert terms["speed"] == pytest.approx(0.05 * 0.316 / scale, abs=1e-5)
        assert terms["moving"] == pytest.approx(0.05 * 0.4 / scale, abs=1e-5)
        got[scale] = terms
    assert {k: v for k, v in got[0.8].items() if k not in ("progress", "speed", "moving")} == pytest.approx(
        {k: v for k, v in got[1.0].items() if k not in ("progress", "speed", "moving")})


def test_reset_speed_one_draws_respawn_speeds_up_to_the_command_limit(env_factory):
    """A respawn's speed is uniform in [0, 0.8) m/s under ours and in [0, 1.0) under the paper's
    code: over 512 vehicles, the paper's reach past 0.8 (about a fifth of them) and ours never do."""
    for limit, extra in ((0.8, []), (1.0, ["rules.reset_speed_one=true"])):
        d = env_factory(extra, num_envs=128, n_agents=4)
        speed = d.sc.speed.abs().flatten()
        assert float(speed.max()) < limit
        share = float((speed > 0.8).float().mean())
        assert (share == 0.0) if limit == 0.8 else (0.13 < share < 0.27)
        assert float(speed.mean()) == pytest.approx(limit / 2, abs=0.05)


# ---- 8. M4's boundary points ---------------------------------------------------------------
def two_lane_map() -> RoadMap:
    """Two same-direction lanes, x in [0, 2]: lane 1 (center y = 0, 11 vertices, 0.2 m apart)
    and its left neighbour lane 2 (center y = 0.15, 21 vertices, 0.1 m apart). The corridor's
    left boundary, y = 0.225, is lane 2's: its vertex index differs from lane 1's at the same x."""
    x1, x2 = np.linspace(0, 2, 11), np.linspace(0, 2, 21)
    line = lambda x, y: np.stack([x, np.full_like(x, y)], 1)  # noqa: E731
    lane1 = Lanelet(1, left=line(x1, 0.075), right=line(x1, -0.075), adj_left=2, adj_left_same=True)
    lane2 = Lanelet(2, left=line(x2, 0.225), right=line(x2, 0.075), adj_right=1, adj_right_same=True)
    lanelets = {1: lane1, 2: lane2}
    return RoadMap("two-lane", lanelets, [build_route("lane1", [1], lanelets)], lane_width=0.15, source="tests")


def test_m4_boundary_points_through_each_boundarys_own_closest_segment(env_factory):
    """Agent at (1.01, 0), M4, ego frame / 1.6. Left boundary (0.1 m vertices): closest segment
    [1.0, 1.1] starts at vertex 10, points 9..13: x = 0.9 .. 1.3 at y = 0.225. Right boundary
    (0.2 m vertices): closest segment [1.0, 1.2], vertex 5, points 4..8: x = 0.8 .. 1.6 at
    y = -0.075. (Indexed through the center line's raw segment, 5, the left points would be
    x = 0.4 .. 0.8.) Ours: the resampled boundaries, x = 0.96 .. 1.28 on both sides."""
    road = two_lane_map()
    layout = 1 + 6 + 1  # speed, reference points, DC; then left (10) and right (10)

    def sides(rules):
        d = env_factory(["obs=no_distance_to_boundaries", *rules], num_envs=1, n_agents=1, road_map=road)
        obs = d.place([[1.01, 0.0]], [0.0])[0, 0]
        return obs[layout:layout + 10], obs[layout + 10:layout + 20]

    def points(xs, y):
        return [v for x in xs for v in ((x - 1.01) / 1.6, y / 1.6)]

    left, right = sides(["rules.own_boundary_index=true"])
    assert left.tolist() == pytest.approx(points([0.9, 1.0, 1.1, 1.2, 1.3], 0.225), abs=1e-6)
    assert right.tolist() == pytest.approx(points([0.8, 1.0, 1.2, 1.4, 1.6], -0.075), abs=1e-6)
    left, right = sides([])
    xs = [0.96, 1.04, 1.12, 1.20, 1.28]
    assert left.tolist() == pytest.approx(points(xs, 0.225), abs=1e-6)
    assert right.tolist() == pytest.approx(points(xs, -0.075), abs=1e-6)


def test_long_raw_segments_are_cut_into_0_1_m_pieces(env_factory, kit):
    """Our copies of the paper's test maps are simplified (a straight stretch is one segment);
    the paper's vertices were about 0.1 m apart, so segments over 0.2 m are cut into equal
    pieces of at most 0.1 m. On a road drawn with one 2 m segment per lanelet, an agent at
    x = 1.01 is on piece [1.0, 1.1] (vertex 10): reference points at vertices 12, 14, 16
    (x = 1.2, 1.4, 1.6) and M4's boundary points at vertices 9..13 (x = 0.9 .. 1.3)."""
    dense, first, pieces = densify(np.array([[0.0, 0.0], [0.15, 0.0], [0.65, 0.0], [0.8, 0.0]]))
    assert dense[:, 0].tolist() == pytest.approx([0.0, 0.15, 0.25, 0.35, 0.45, 0.55, 0.65, 0.8])
    assert (first.tolist(), pieces.tolist()) == ([0, 1, 6], [1, 5, 1])
    road = kit.straight_road_map(0.075)
    for la in road.lanelets.values():
        la.left, la.right = la.left[[0, -1]], la.right[[0, -1]]
    road = RoadMap("coarse", road.lanelets, [build_route("coarse", [1, 2], road.lanelets)], 0.15, "tests")
    d = env_factory(["obs=no_distance_to_boundaries", "rules.raw_center_line=true", "rules.own_boundary_index=true"],
                    num_envs=1, n_agents=1, road_map=road)
    obs = d.place([[1.01, 0.0]], [0.0])[0, 0]
    assert obs[1:7:2].tolist() == pytest.approx([(x - 1.01) / 1.6 for x in (1.2, 1.4, 1.6)], abs=1e-6)
    assert obs[8:18:2].tolist() == pytest.approx([(x - 1.01) / 1.6 for x in (0.9, 1.0, 1.1, 1.2, 1.3)], abs=1e-6)


# ---- 9. bird's-eye view scale in evaluation -------------------------------------------------
def shifted_road() -> RoadMap:
    """The straight road moved up by 1 m: points in x 0..4, y 0.925..1.075, so its world is
    (0 + 4, 0.925 + 1.075) = 4 x 2 m."""
    x = np.linspace(0, 4, 21)
    la = Lanelet(1, left=np.stack([x, np.full_like(x, 1.075)], 1), right=np.stack([x, np.full_like(x, 0.925)], 1))
    return RoadMap("shifted", {1: la}, [build_route("shifted", [1], {1: la})], lane_width=0.15, source="tests")


def test_test_world_size_divides_the_birds_eye_view_by_the_test_maps_size(env_factory):
    road = shifted_road()
    for rules, mode, world in (([], "test", (4.5, 4.0)), (["rules.test_world_size=true"], "train", (4.5, 4.0)),
                               (["rules.test_world_size=true"], "test", (4.0, 2.0))):
        d = env_factory(["obs=no_ego_view", *rules], num_envs=1, n_agents=1, road_map=road, mode=mode)
        obs = d.place([[1.01, 1.01]], [0.0])
        assert obs[0, 0, :2].tolist() == pytest.approx([1.01 / world[0], 1.01 / world[1]], abs=1e-6)


# ---- 10. collisions ------------------------------------------------------------------------
def test_strict_crossings_touching_vehicles_and_boundaries_do_not_count(env_factory, wide_road, straight_road):
    """Side by side 0.08 m apart the rectangles share an edge: ours a collision, the paper's
    strict edge test not; two rectangles crossing at 90 degrees collide under both. The flags
    the metrics read stay ours; the reward and the episode's end follow the switch."""
    def run(rules, pos, heading, road, n):
        d = env_factory(rules, num_envs=1, n_agents=n, road_map=road)
        d.place(pos, heading)
        nxt = d.step([0.0, 0.0])
        return (float(d.sc.terms["agent_collision"][0, 0]), float(d.sc.terms["lane_collision"][0, 0]),
                bool(nxt["terminated"]), float(nxt["agents", "info", "agent_collision"][0, 0]))

    touching = ([[1.0, 0.0], [1.0, 0.08]], [0.0, 0.0])
    assert run([], *touching, wide_road, 2) == (-1.0, 0.0, True, 1.0)
    assert run(["rules.strict_crossings=true"], *touching, wide_road, 2) == (0.0, 0.0, False, 1.0)
    crossing = ([[1.0, 0.0], [1.0, 0.05]], [0.0, math.pi / 2])
    assert run(["rules.strict_crossings=true"], *crossing, wide_road, 2)[:3] == (-1.0, 0.0, True)
    # the left side at y = 0.035 + 0.04 = 0.075 lies on the boundary: touching, not crossing
    assert run([], [[1.0, 0.035]], [0.0], straight_road, 1)[1:3] == (-1.0, True)
    assert run(["rules.strict_crossings=true"], [[1.0, 0.035]], [0.0], straight_road, 1)[1:3] == (0.0, False)
    assert run(["rules.strict_crossings=true"], [[1.0, 0.06]], [0.0], straight_road, 1)[1:3] == (-1.0, True)


def test_env_lane_flag_marks_every_agent_of_the_environment(env_factory, straight_road):
    """Agent 0 crosses the boundary, agent 1 drives in the middle: the paper's lane-collision
    info flag is set for both; the penalty stays agent 0's."""
    for rules, flags in (([], [1.0, 0.0]), (["rules.env_lane_flag=true"], [1.0, 1.0])):
        d = env_factory(rules, num_envs=1, n_agents=2, road_map=straight_road, mode="test")
        d.place([[1.0, 0.06], [2.0, 0.0]], [0.0, 0.0])
        nxt = d.step([0.0, 0.0])
        assert nxt["agents", "info", "lane_collision"][0, :, 0].tolist() == flags
        assert d.sc.terms["lane_collision"][0].tolist() == [-1.0, 0.0]


# ---- 11. steering penalty, time-outs, respawns ---------------------------------------------
def test_lagged_steering_penalty(env_factory, wide_road):
    """Steering 0, then 0.5, 0.5, 0.5 rad: ours penalises the change at the first 0.5 (current
    vs previous), the paper one step later (previous vs the one before):
    -0.02 (0.5 - 10 deg) / 50 deg = -0.0074592."""
    pen = -0.02 * (0.5 - STEER_FREE) / STEER_SCALE
    assert pen == pytest.approx(-0.0074592, abs=1e-7)
    for rules, expect in (([], [pen, 0.0, 0.0]), (["rules.lagged_steering=true"], [0.0, pen, 0.0])):
        d = env_factory(rules, num_envs=1, n_agents=1, road_map=wide_road)
        d.place([[1.0, 0.0]], [0.0], speed=[0.0], steering=[0.0])
        got = []
        for _ in range(3):
            d.step([0.0, 0.5])
            got.append(float(d.sc.terms["steering_change"][0, 0]))
        assert got == pytest.approx(expect, abs=1e-7)


def test_timeout_is_terminal_not_truncated(env_factory, wide_road):
    for rules, terminated in (([], False), (["rules.timeout_terminal=true"], True)):
        d = env_factory(["env.max_steps=3", *rules], num_envs=1, n_agents=1, road_map=wide_road)
        d.place([[1.0, 0.0]], [0.0])
        for _ in range(3):
            nxt = d.step([0.0, 0.0])
        assert (bool(nxt["terminated"]), bool(nxt["truncated"]), bool(nxt["done"])) == (terminated, not terminated, True)


def test_stale_observation_after_a_test_mode_respawn(env_factory, straight_road):
    """A vehicle across the boundary, standing still, collides and respawns (test mode). The
    paper's observation after the step is the one of the state it collided in (what placing it
    there observed); ours is the new state's."""
    for rules, stale in (([], False), (["rules.stale_respawn_obs=true"], True)):
        d = env_factory(rules, num_envs=1, n_agents=1, road_map=straight_road, mode="test")
        before = d.place([[1.0, 0.06]], [0.0], speed=[0.0])
        nxt = d.step([0.0, 0.0])
        assert bool(nxt["agents", "info", "respawned"][0, 0]) and float(nxt["agents", "info", "lane_collision"][0, 0]) == 1.0
        assert torch.equal(nxt["agents", "observation"], before) == stale
        assert float(d.sc.pos[0, 0, 1]) == pytest.approx(0.0, abs=1e-6)  # respawned on the center line


@pytest.mark.slow  # plans two studies of 12 and 8 jobs: 5 s
def test_the_rule_families_split_the_paper_rules_and_the_screen_declares_them():
    from sigmarl.sweep import plan_sweep

    families = ["dynamics", "observation", "collisions", "episodes", "reward"]
    on = {f: switches_on(compose_config([f"rules=paper_{f}"]).rules) for f in families}
    assert on["dynamics"] == ["drag_dynamics"] and "own_boundary_index" in on["observation"]
    assert sorted(s for f in families for s in on[f]) == sorted(ALL)  # each switch in exactly one
    plan = plan_sweep(["study=paper_switches", "seeds=[0]", "tracking.enabled=false"], cores=2)
    jobs = {j.label: j for j in plan.jobs}
    assert len(jobs) == 12
    for f in families[:4]:
        for model, preset in [("M0", "full"), ("M4", "no_distance_to_boundaries")]:
            cfg = compose_config(jobs[f"{model}-{f}"].overrides)
            assert cfg.obs.preset == preset and switches_on(cfg.rules) == on[f]
            assert cfg.ppo.iterations == 250 and cfg.run_dir == f"results/paper-switches/{model}-{f}/seed0"
    # the runs under ours and under all of the paper's rules are study=paper_rules' own, reused
    rules = {j.label: j for j in plan_sweep(["study=paper_rules", "seeds=[0]", "tracking.enabled=false"], cores=2).jobs}
    for label, folder in [("M0", "paper-budget"), ("M4", "paper-budget"), ("M0-paper", "paper-rules"),
                          ("M4-paper", "paper-rules")]:
        assert jobs[label].run_dir == f"results/{folder}/{label}/seed0"
        # the committed runs were trained before the reward family existed: the studies name it off
        committed = read_run_config(Path(__file__).parents[1] / "results" / folder / label / "seed0" / "config.yaml")
        assert jobs[label].fingerprint == fingerprint(committed)
        assert jobs[label].fingerprint == rules[label].fingerprint
    study = plan.config.study
    assert study.baselines["M4-observation"] == "M4" and study.interactions["observation"] == ["M4-observation", "M0-observation"]


def test_the_other_raw_vertex_emulation_cuts_into_pieces_nearest_0_1_m():
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "scripts" / "densify_check.py"
    spec = importlib.util.spec_from_file_location("densify_check", path)
    check = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(check)
    line = np.array([[0.0, 0.0], [0.216, 0.0], [0.266, 0.0], [0.266, 0.36]])
    dense, first, pieces = check.densify_nearest(line)
    assert pieces.tolist() == [2, 1, 4]  # 0.216 m: two of 0.108 (shipped: three of 0.072); 0.36 m: four of 0.09
    assert first.tolist() == [0, 2, 3]
    expected = np.array([[0.108, 0]] * 2 + [[0.05, 0]] + [[0, 0.09]] * 4)
    assert np.diff(dense, axis=0) == pytest.approx(expected)
    assert densify(line)[2].tolist() == [3, 1, 4]
