"""The road map a run drives on (`map.*`, conf/map/<name>.yaml)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from sigmarl.config.ranges import ranged


@dataclass
class MapConfig:
    """A road map: the CPM Lab map, a procedural test map, or a user's OSM file."""

    name: str = "cpm_intersection"
    """The map's name (conf/map/<name>.yaml); labels figures and `sigmarl maps`."""
    kind: str = ranged("cpm", choices=("cpm", "intersection", "on_ramp", "roundabout", "osm"))
    """Which builder makes it: cpm | intersection | on_ramp | roundabout | osm."""
    route_set: str = ranged("intersection", choices=("intersection", "loops"))
    """cpm only: the central intersection's 24 routes (intersection) or the whole map's 7 loops (loops)."""
    lane_width: float = ranged(0.20, lo=0, lo_open=True)
    """Lane width in m of procedural and OSM maps (the CPM map is fixed at 0.15)."""
    # intersection and roundabout builders: arms at angles 2*pi*k/n_arms (k=0 east)
    arm_length: float = ranged(1.25, lo=0, lo_open=True)
    """Intersection and roundabout: length in m of each arm's straight lanes."""
    arm_lengths: list[float] = ranged(factory=list, lo=0, lo_open=True)
    """Per-arm lengths in m: arm k is arm_lengths[k % len] long (empty: arm_length for all)."""
    n_arms: int = ranged(4, lo=3, hi=6)
    """Intersection and roundabout: number of arms, at angles 2 pi k / n_arms (k = 0 east)."""
    junction_offset: float = ranged(0.45, lo=0, lo_open=True)
    """Intersection: distance in m from the junction's center to where the arms start."""
    radius: float = ranged(0.55, lo=0, lo_open=True)
    """Roundabout: the ring's center-line radius in m."""
    entry_radius: float = ranged(0.35, lo=0, lo_open=True)
    """Roundabout: radius in m of the arcs joining the arms to the ring."""
    n_ramps: int = ranged(2, lo=1, hi=64, size=True)
    """On-ramp: number of ramps joining the main road."""
    main_length: float = ranged(4.1, lo=0, lo_open=True)
    """On-ramp: length in m of the main road."""
    ramp_drop: float = ranged(1.63, lo=0, lo_open=True)
    """On-ramp: how far in m below the main road's center line a ramp starts."""
    ramp_angle: float = ranged(45.0, lo=10, hi=80, unit="degrees")
    """On-ramp: the ramps' angle to the main road, in degrees."""
    ramp_radius: float = ranged(0.8, lo=0, lo_open=True)
    """On-ramp: radius in m of the bend onto the main road."""
    path: str = ""
    """kind=osm: the OSM file (SigmaRL center-line ways or Lanelet2 relations)."""
    routes: list[Any] = field(default_factory=list)
    """kind=osm: routes as lists of way/lanelet ids (last id = first: a loop); empty: all from the lanelet graph."""
