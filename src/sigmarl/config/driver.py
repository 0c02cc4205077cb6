"""Who drives (`driver.*`): the trained MAPPO policy, or a rule-based driver that needs no
training (`sigmarl.evaluation.rule_based`), a yardstick outside RL that a study can list as a
variant (`RB: [driver.kind=rule_based]`)."""

from __future__ import annotations

from dataclasses import dataclass, fields

DRIVERS = ("mappo", "rule_based")


@dataclass
class DriverConfig:
    """Who drives: the trained MAPPO policy, or the rule-based driver (pure pursuit and IDM)."""

    kind: str = "mappo"
    """mappo: the policy trained with MAPPO | rule_based: pure pursuit on the route's center line and IDM car following; not trained, evaluated like a seed"""
    lookahead_m: float = 0.25
    """rule_based: m along the center line ahead of the vehicle to the point pure pursuit steers at"""
    desired_speed: float = 0.7
    """rule_based: m/s IDM drives at on a free road (at most env.vehicle.max_speed)"""
    time_headway: float = 0.5
    """rule_based: s of IDM's time gap to the vehicle ahead"""
    min_gap_m: float = 0.1
    """rule_based: m of IDM's bumper-to-bumper gap at standstill"""
    max_accel: float = 1.0
    """rule_based: m/s^2 of IDM's largest acceleration"""
    comfortable_decel: float = 1.5
    """rule_based: m/s^2 of IDM's comfortable deceleration"""
    horizon_m: float = 1.5
    """rule_based: m of center line ahead searched for the vehicle ahead"""
    on_path_m: float = 0.08
    """rule_based: a vehicle whose center is this close to the path ahead is on it"""
    aligned_deg: float = 60.0
    """rule_based: a vehicle on the path is followed when its heading is within this many degrees of the path's (crossing traffic is not)"""


# the keys as the fingerprint names them, at the value every earlier run trained with
ADDED_KEYS = {f"driver.{f.name}": f.default for f in fields(DriverConfig)}


def check_driver(driver: DriverConfig) -> None:
    """A driver that can drive: a known kind and positive distances, speeds and rates."""
    import difflib

    from sigmarl.errors import SigmarlError

    if driver.kind not in DRIVERS:
        close = difflib.get_close_matches(driver.kind, DRIVERS, n=1)  # not sigmarl.config.suggest: it imports the config
        raise SigmarlError(f"driver.kind must be one of {', '.join(DRIVERS)}, got {driver.kind!r}"
                           + (f" (did you mean {close[0]}?)" if close else ""))
    for f in fields(driver):
        value = getattr(driver, f.name)
        if f.name != "kind" and not value > 0:
            raise SigmarlError(f"driver.{f.name} must be positive, got {value}")
    if driver.aligned_deg > 180:
        raise SigmarlError(f"driver.aligned_deg must be at most 180 degrees, got {driver.aligned_deg}")
