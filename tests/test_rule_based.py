"""The rule-based driver (`driver.kind=rule_based`): its steering and speed commands against
pure pursuit and IDM worked out by hand on a straight road and on a circle, and its runs as a
study variant (evaluated, never trained, once whatever the seeds)."""

from __future__ import annotations

import math

import pytest
import torch

from sigmarl.config.driver import DriverConfig
from sigmarl.errors import SigmarlError
from sigmarl.evaluation.rule_based import RuleBasedDriver, idm_acceleration, pure_pursuit_steering

P = DriverConfig()  # v0 0.7 m/s, T 0.5 s, s0 0.1 m, a 1 m/s^2, b 1.5 m/s^2, look-ahead 0.25 m


def test_pure_pursuit_on_a_straight_line_by_hand():
    # rear axle at the origin heading +x, target (0.3, 0.1): ld = sqrt(0.1), sin(alpha) = 0.1 / ld,
    # delta = atan(2 L sin(alpha) / ld) = atan(2 * 0.16 * 0.1 / 0.1) = atan(0.32)
    rear, target = torch.tensor([[0.0, 0.0], [0.0, 0.0]]), torch.tensor([[0.3, 0.1], [0.3, 0.0]])
    delta = pure_pursuit_steering(rear, torch.zeros(2), target)
    assert delta.tolist() == pytest.approx([0.3097029, 0.0], abs=1e-6)


@pytest.mark.parametrize("radius", [0.5, 1.2])
@pytest.mark.parametrize("turn", [-1, 1])
def test_pure_pursuit_on_a_circle_steers_the_circle(radius, turn):
    # a target anywhere on the circle tangent to the heading at the rear axle: pure pursuit's
    # arc is that circle, so delta = atan(L / R) (left turns positive), whatever the target
    theta = torch.tensor([0.2, 0.5, 1.0])
    target = torch.stack([radius * theta.sin(), turn * radius * (1 - theta.cos())], -1)
    heading = torch.full((3,), 0.7)  # the same scene rotated by 0.7 rad about the rear axle
    c, s = math.cos(0.7), math.sin(0.7)
    rotated = target @ torch.tensor([[c, s], [-s, c]])
    delta = pure_pursuit_steering(torch.zeros(3, 2), heading, rotated)
    assert delta.tolist() == pytest.approx([turn * math.atan(0.16 / radius)] * 3, abs=1e-5)


def test_idm_by_hand():
    # free road: a (1 - (v/v0)^4); at v0 it is 0, standing still it is a
    free = idm_acceleration(torch.tensor([0.0, 0.7, 0.3]), torch.full((3,), math.inf), torch.zeros(3), P)
    assert free.tolist() == pytest.approx([1.0, 0.0, 1 - (0.3 / 0.7) ** 4], abs=1e-6)
    # v 0.5, gap 0.3, closing 0.2: s* = 0.1 + 0.5 * 0.5 + 0.5 * 0.2 / (2 sqrt(1.5)) = 0.390825;
    # a = 1 - (0.5/0.7)^4 - (0.390825/0.3)^2 = 1 - 0.260308 - 1.697150 = -0.957458
    follow = idm_acceleration(torch.tensor([0.5]), torch.tensor([0.3]), torch.tensor([0.2]), P)
    assert follow.item() == pytest.approx(-0.957458, abs=1e-5)


@pytest.fixture
def road(env_factory, straight_road):
    return env_factory(road_map=straight_road, num_envs=1, n_agents=2)


def test_commands_on_a_straight_road_by_hand(road):
    # Center points every 0.08 m on y = 0. Agent 0 at (0.98, 0.03), 0.5 m/s: its center point is
    # x 0.96, 0.02 m behind it; the look-ahead point round((0.25 + 0.02) / 0.08) = 3 points on,
    # x 1.20. Rear axle (0.90, 0.03): delta = -atan(2 * 0.16 * 0.03 / (0.30^2 + 0.03^2)) = -0.105221.
    # Agent 1 at (1.5, 0), 0.3 m/s, heading the road's way, is on agent 0's path from its sixth
    # point on (x 1.44, 0.06 m from it): arc 6 * 0.08 - 0.02 = 0.46 m, gap 0.46 - 0.16 = 0.30 m,
    # closing 0.2 m/s, so IDM gives -0.957458 m/s^2 (above) and the command 0.5 - 0.957458 * 0.05.
    # Agent 1 has a free road: 0.3 + 0.05 (1 - (0.3/0.7)^4), straight on.
    road.place([[0.98, 0.03], [1.5, 0.0]], [0.0, 0.0], speed=[0.5, 0.3])
    action = RuleBasedDriver(P).action(road.sc)[0]
    assert action[0].tolist() == pytest.approx([0.5 - 0.957458 * 0.05, -0.105221], abs=1e-5)
    assert action[1].tolist() == pytest.approx([0.3 + 0.05 * (1 - (0.3 / 0.7) ** 4), 0.0], abs=1e-5)


def test_a_vehicle_crossing_the_path_is_not_followed(road):
    # the same scene with agent 1 heading across the road: agent 0 has a free road (it does not yield)
    road.place([[0.98, 0.03], [1.5, 0.0]], [0.0, math.pi / 2], speed=[0.5, 0.3])
    action = RuleBasedDriver(P).action(road.sc)[0]
    assert action[0, 0].item() == pytest.approx(0.5 + 0.05 * (1 - (0.5 / 0.7) ** 4), abs=1e-5)


def test_it_keeps_its_lane_on_a_paper_scenario(kit):
    # alone on the roundabout's routes (curves of 0.35-0.55 m radius): no lane contact, close to
    # its center line, near its desired speed
    from sigmarl.evaluation.rollout import evaluate_policy

    cfg = kit.cfg(("driver.kind=rule_based", "obs.n_nearest=0"))
    rows = evaluate_policy(RuleBasedDriver(cfg.driver), cfg, "Roundabout", n_sims=4, steps=200, n_agents=1,
                           progress=False)
    assert (rows["CR_total"] == 0).all()
    assert rows["CD"].max() < 2.0  # cm
    assert rows["AS"].min() > 0.6


def test_bad_parameters_are_refused_in_one_line():
    from sigmarl.compose import compose_config

    with pytest.raises(SigmarlError, match="did you mean rule_based"):
        compose_config(["driver.kind=rule_basd"])
    with pytest.raises(SigmarlError, match="driver.time_headway must be positive"):
        compose_config(["driver.time_headway=0"])


def test_a_rule_based_variant_is_evaluated_once_and_never_trained(tmp_path):
    from sigmarl.sweep.job import run_job
    from sigmarl.sweep.plan import plan_sweep

    overrides = ["study=rule_based", f"runs_root={tmp_path}", "tracking.enabled=false", "eval.n_sims=2",
                 "eval.steps=20", "eval.scenarios=[Intersection]"]
    plan = plan_sweep([*overrides, "seeds=[3,4,5]"])
    assert [j.key for j in plan.jobs] == ["RB/seed3"]  # deterministic: one run, whatever the seeds
    from sigmarl.compose import compose_config

    assert run_job(compose_config(plan.jobs[0].overrides)) == "done"
    run = tmp_path / "RB" / "seed3"
    assert sorted(p.name for p in run.iterdir() if not p.name.startswith(".")) == [
        "config.yaml", "evaluated.txt", "evaluation.json", "evaluation_rows.csv"]  # no checkpoint, no curve
    import pandas as pd

    rows = pd.read_csv(run / "evaluation_rows.csv")
    assert len(rows) == 2 and set(rows["model"]) == {"RB"} and set(rows["scenario"]) == {"Intersection"}
