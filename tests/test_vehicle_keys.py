"""The vehicle's limits as config keys (`env.vehicle.*`): the CPM Lab vehicle's by default (the
published runs keep their fingerprints), commands clamped to them in the environment (a step
checked against the kinematic bicycle worked out by hand), bad values refused at composition."""

from __future__ import annotations

import math

import pytest
import torch
from cli_errors import one_line_exit_2

from sigmarl.compose import compose_config
from sigmarl.params import DT

OFF = "tracking.enabled=false"


def test_the_defaults_are_the_cpm_lab_vehicles():
    v = compose_config([OFF]).env.vehicle
    assert v.max_speed == 0.8 and v.max_steering_deg == 35.0 and v.max_steering == math.radians(35)


def test_a_limit_at_its_default_keeps_the_fingerprint_and_another_value_changes_it():
    base = compose_config([OFF]).fingerprint
    assert compose_config([OFF, "env.vehicle.max_speed=0.8", "env.vehicle.max_steering_deg=35"]).fingerprint == base
    assert compose_config([OFF, "env.vehicle.max_speed=1.0"]).fingerprint != base
    assert compose_config([OFF, "env.vehicle.max_steering_deg=20"]).fingerprint != base


def test_the_action_range_is_the_configured_limits(env_factory, wide_road):
    d = env_factory(["env.vehicle.max_speed=1.0", "env.vehicle.max_steering_deg=20"], road_map=wide_road,
                    num_envs=1, n_agents=1, mode="test")
    d.place([[0.5, 0.0]], [0.0], speed=[0.0], steering=[0.0])
    delta = math.radians(20)
    d.step([1.0, delta])  # full speed, full lock: accepted
    sc = d.sc
    assert sc.speed.item() == pytest.approx(1.0) and sc.steering.item() == pytest.approx(delta)
    # the kinematic bicycle by hand: slip angle atan(l_r / L tan(delta)), l_r = 0.08 m, L = 0.16 m
    beta = math.atan(0.5 * math.tan(delta))
    omega = 1.0 / 0.16 * math.cos(beta) * math.tan(delta)
    assert sc.heading.item() == pytest.approx(omega * DT, rel=1e-5)
    with pytest.raises(AssertionError, match=r"out of its range \[1.0, 0.349065"):
        d.step([1.0, delta + 0.01])  # VMAS holds every action to the agent's range


def test_the_default_vehicle_keeps_the_papers_range(env_factory, wide_road):
    d = env_factory([], road_map=wide_road, num_envs=1, n_agents=1, mode="test")
    d.place([[0.5, 0.0]], [0.0], speed=[0.0], steering=[0.0])
    d.step([0.8, math.radians(35)])
    assert torch.isclose(d.sc.speed, torch.tensor(0.8)).all()
    with pytest.raises(AssertionError, match=r"out of its range \[0.8, 0.610865"):
        d.step([0.81, 0.0])


@pytest.mark.parametrize(("override", "message"), [
    ("env.vehicle.max_speed=0", "env.vehicle.max_speed must be positive (m/s), got 0.0"),
    ("env.vehicle.max_steering_deg=90", "env.vehicle.max_steering_deg must be in (0, 90) degrees, got 90.0"),
    ("env.vehicle.top_speed=1", "env.vehicle.top_speed"),
])
def test_bad_limits_are_one_line(override, message, capsys):
    line = one_line_exit_2(["train", override, OFF], capsys)
    assert message in line
