"""The vehicle's limits as config keys (`env.vehicle.*`): the CPM Lab vehicle's by default
(`sigmarl.env.params.VEHICLE`), so that a study can ablate them like any other setting. The
environment clamps the policy's commands to them; the observation's and the reward's speed
scales stay the paper's, so that a policy sees and is paid on one scale whatever it drives."""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

from sigmarl.env.params import VEHICLE


@dataclass
class VehicleConfig:
    """The vehicle's limits (the CPM Lab vehicle's by default)."""

    max_speed: float = VEHICLE.max_speed
    """m/s: the fastest a speed command drives, forwards or backwards"""
    max_steering_deg: float = math.degrees(VEHICLE.max_steering)
    """degrees: the largest steering angle a command reaches, left or right"""

    @property
    def max_steering(self) -> float:
        return math.radians(self.max_steering_deg)


# the keys as the fingerprint names them, at the value every earlier run trained with
ADDED_KEYS = {f"env.vehicle.{f.name}": f.default for f in fields(VehicleConfig)}


def check_vehicle(vehicle: VehicleConfig) -> None:
    """Limits a vehicle can drive with: a positive top speed, a steering angle below 90 degrees."""
    from sigmarl.errors import SigmarlError

    if not vehicle.max_speed > 0:
        raise SigmarlError(f"env.vehicle.max_speed must be positive (m/s), got {vehicle.max_speed}")
    if not 0 < vehicle.max_steering_deg < 90:
        raise SigmarlError(f"env.vehicle.max_steering_deg must be in (0, 90) degrees, got {vehicle.max_steering_deg}")
