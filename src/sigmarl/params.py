"""The paper's constants, in one home: the vehicle, the sample time, the observation's
normalisers and the reward's weights. Every env module reads them from here."""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class Vehicle:
    """A CPM Lab vehicle: a 0.16 m x 0.08 m rectangle, center of gravity at its middle."""

    length: float = 0.16  # m
    width: float = 0.08  # m
    l_r: float = 0.08  # m, center of gravity to rear axle
    wheelbase: float = 0.16  # m
    max_speed: float = 0.8  # m/s, |v|
    max_steering: float = math.radians(35)  # |delta|

    @property
    def diagonal(self) -> float:
        return math.hypot(self.length, self.width)

    @property
    def half_diagonal(self) -> float:
        """Every point of the box is this close to its center."""
        return self.diagonal / 2


VEHICLE = Vehicle()
DT = 0.05  # s, sample time
CPM_LANE_WIDTH = 0.15  # m, the training map's lanes (the reward's distance scales follow from it)


@dataclass(frozen=True)
class Normalisers:
    """Observation scales: constants of the policy, not of the map (a policy must see the
    same scale on an unseen map)."""

    world: tuple[float, float] = (4.5, 4.0)  # m, the training world, also on unseen maps
    ego: float = 1.6  # m, ego-frame points
    speed: float = VEHICLE.max_speed  # m/s
    distance: float = 0.45  # m, DA, DB and DC distances
    heading: float = 2 * math.pi


NORMALISERS = Normalisers()


@dataclass(frozen=True)
class RewardWeights:
    """The paper's reward table: each term's weight and the scales of its shaping functions."""

    progress: float = 0.10
    speed: float = 0.05
    moving: float = 0.05
    near_boundary: float = -0.20
    near_agents: float = -0.20
    center_line_deviation: float = -0.02
    steering_change: float = -0.02
    agent_collision: float = -1.0
    lane_collision: float = -1.0
    ref_weights: tuple[float, ...] = (1.0 / 1.8, 0.6 / 1.8, 0.2 / 1.8)  # the reference points
    near_boundary_at: float = 0.9 * (CPM_LANE_WIDTH - VEHICLE.width) / 2  # 0.0315 m
    deviation_scale: float = (CPM_LANE_WIDTH - VEHICLE.width) / 2  # 0.035 m
    # (l + w) / 2 and twice that, center to center
    near_agent_at: tuple[float, float] = ((VEHICLE.length + VEHICLE.width) / 2, VEHICLE.length + VEHICLE.width)
    steering_free: float = math.radians(10)
    steering_scale: float = math.radians(50)


REWARD = RewardWeights()
