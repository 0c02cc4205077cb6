"""The vehicle's limits as config keys (`env.vehicle.*`): the CPM Lab vehicle's by default
(`sigmarl.params.VEHICLE`), so that a study can ablate them like any other setting. The
environment clamps the policy's commands to them; the observation's and the reward's speed
scales stay the paper's, so that a policy sees and is paid on one scale whatever it drives."""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

from sigmarl.config.ranges import ranged
from sigmarl.params import VEHICLE


@dataclass
class VehicleConfig:
    """The vehicle's limits (the CPM Lab vehicle's by default)."""

    max_speed: float = ranged(VEHICLE.max_speed, lo=0, lo_open=True, unit="m/s")
    """m/s: the fastest a speed command drives, forwards or backwards"""
    max_steering_deg: float = ranged(math.degrees(VEHICLE.max_steering), lo=0, hi=90, lo_open=True, hi_open=True,
                                     unit="degrees")
    """degrees: the largest steering angle a command reaches, left or right"""

    @property
    def max_steering(self) -> float:
        return math.radians(self.max_steering_deg)


# the keys as the fingerprint names them, at the value every earlier run trained with
ADDED_KEYS = {f"env.vehicle.{f.name}": f.default for f in fields(VehicleConfig)}

