"""The road map a run drives on (`map.*`, conf/map/<name>.yaml): one record per kind of map.

A kind of map is one dataclass here, declared with `@map_kind(name, builder=...)`: its keys
(each with its help line and range), the function that builds its `RoadMap` from them
("module:function", imported when a map of that kind is loaded, `sigmarl.maps.load_map`) and
the keys it cannot do without. `MapConfig`, the `map` group of every config, is the union of
every kind's keys, because a run's config.yaml holds them all whichever kind it builds; the
`kind` key's choices, what a map's training run records (`map_keys`) and the keys a fingerprint
leaves out (`later_map_keys`) are read from the records. A new kind of map is its record here
and its builder.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

from sigmarl.config.ranges import ranged
from sigmarl.errors import MapError


@dataclass(frozen=True)
class MapKind:
    name: str
    record: type  # the dataclass of the keys this kind is built from
    builder: str  # "module:function": MapConfig -> RoadMap
    needs: dict[str, str]  # key -> an example value: a key that must not be empty

    @property
    def keys(self) -> tuple[str, ...]:
        return tuple(f.name for f in dataclasses.fields(self.record))


MAP_KINDS: dict[str, MapKind] = {}
# The kinds every recorded fingerprint was computed with: their keys are always fingerprinted.
# A kind declared after them adds keys that a fingerprint leaves out at their defaults.
RECORDED_KINDS = ("cpm", "intersection", "roundabout", "on_ramp", "osm")


def map_kind(name: str, *, builder: str, needs: dict[str, str] | None = None):
    """Declare a kind of map: the decorated dataclass holds its keys."""
    def declare(record: type) -> type:
        MAP_KINDS[name] = MapKind(name, record, builder, dict(needs or {}))
        return record
    return declare


def map_keys(kind: str) -> tuple[str, ...]:
    """The keys a map of `kind` is built from (none for an unknown kind)."""
    return MAP_KINDS[kind].keys if kind in MAP_KINDS else ()


def kind_of(cfg: Any) -> MapKind:
    """The kind of map `cfg` (a MapConfig) declares, after checking the keys it needs."""
    if cfg.kind not in MAP_KINDS:
        raise MapError(f"unknown map kind {cfg.kind!r}; choose {', '.join(MAP_KINDS)}")
    kind = MAP_KINDS[cfg.kind]
    for key, example in kind.needs.items():
        if not getattr(cfg, key):
            raise MapError(f"map.kind={kind.name} needs map.{key}={example}")
    return kind


def later_map_keys() -> dict[str, Any]:
    """`map.<key>` -> its default, for the keys of kinds declared after `RECORDED_KINDS`: a
    fingerprint leaves them out at that value (`sigmarl.identity`)."""
    recorded = {key for name in RECORDED_KINDS for key in map_keys(name)}
    return {f"map.{f.name}": f.default_factory() if f.default_factory is not dataclasses.MISSING else f.default
            for f in dataclasses.fields(MapConfig) if f.name not in recorded and f.name not in ("name", "kind")}


@dataclass
class LaneWidth:
    lane_width: float = ranged(0.20, lo=0, lo_open=True)
    """Lane width in m of procedural and OSM maps (the CPM map is fixed at 0.15)."""


@dataclass
class Arms(LaneWidth):
    arm_length: float = ranged(1.25, lo=0, lo_open=True)
    """Intersection and roundabout: length in m of each arm's straight lanes."""
    arm_lengths: list[float] = ranged(factory=list, lo=0, lo_open=True)
    """Per-arm lengths in m: arm k is arm_lengths[k % len] long (empty: arm_length for all)."""
    n_arms: int = ranged(4, lo=3, hi=6)
    """Intersection and roundabout: number of arms, at angles 2 pi k / n_arms (k = 0 east)."""


@map_kind("cpm", builder="sigmarl.maps.cpm:cpm_map")
@dataclass
class CpmMap:
    """The CPM Lab map."""

    route_set: str = ranged("intersection", choices=("intersection", "loops"))
    """cpm only: the central intersection's 24 routes (intersection) or the whole map's 7 loops (loops)."""


@map_kind("intersection", builder="sigmarl.maps.builders:intersection_map")
@dataclass
class IntersectionMap(Arms):
    """A procedural intersection: n_arms two-way arms meeting at a junction."""

    junction_offset: float = ranged(0.45, lo=0, lo_open=True)
    """Intersection: distance in m from the junction's center to where the arms start."""


@map_kind("roundabout", builder="sigmarl.maps.builders:roundabout_map")
@dataclass
class RoundaboutMap(Arms):
    """A procedural roundabout: a one-lane ring with n_arms two-way arms."""

    radius: float = ranged(0.55, lo=0, lo_open=True)
    """Roundabout: the ring's center-line radius in m."""
    entry_radius: float = ranged(0.35, lo=0, lo_open=True)
    """Roundabout: radius in m of the arcs joining the arms to the ring."""


@map_kind("on_ramp", builder="sigmarl.maps.builders:on_ramp_map")
@dataclass
class OnRampMap(LaneWidth):
    """A procedural main road with ramps joining it."""

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


@map_kind("osm", builder="sigmarl.maps:osm_map", needs={"path": "<file.osm>"})
@dataclass
class OsmMap(LaneWidth):
    """A user's OSM file (SigmaRL center-line ways or Lanelet2 relations)."""

    path: str = ""
    """kind=osm: the OSM file (SigmaRL center-line ways or Lanelet2 relations)."""
    routes: list[Any] = field(default_factory=list)
    """kind=osm: routes as lists of way/lanelet ids (last id = first: a loop); empty: all from the lanelet graph."""


# The `map` group: every kind above in one record.


@dataclass
class MapName:
    name: str = "cpm_intersection"
    """The map's name (conf/map/<name>.yaml); labels figures and `sigmarl maps`."""


def _union() -> type:
    """`MapConfig`: the name, the kind, then every kind's keys in the order they are declared
    (a key two kinds share, such as lane_width, once: the same field)."""
    fields: dict[str, dataclasses.Field] = {}
    sources: dict[str, type] = {}
    for record in (MapName, *(k.record for k in MAP_KINDS.values())):
        for f in dataclasses.fields(record):
            if f.name in fields:
                continue
            fields[f.name], sources[f.name] = _copy(f), _declaring(record, f.name)
            if record is MapName:
                kinds = tuple(MAP_KINDS)
                fields["kind"] = _copy(ranged(kinds[0], choices=kinds), "str")
    cls = dataclasses.make_dataclass("MapConfig", [(n, f.type, f) for n, f in fields.items()])
    cls.__module__ = __name__  # its annotations ("list[float]") are read in this module
    cls.__doc__ = "A road map: the CPM Lab map, a procedural test map, or a user's OSM file."
    cls.FIELD_SOURCES = sources  # where each key's help line is written (`sigmarl.config.help`)
    cls.FIELD_HELP = {"kind": "Which builder makes it: " + " | ".join(MAP_KINDS) + "."}
    return cls


def _copy(f: dataclasses.Field, type_: str | None = None) -> dataclasses.Field:
    """A fresh field of `f`'s default, factory and range (a field belongs to one class)."""
    new = field(default=f.default, default_factory=f.default_factory, metadata=f.metadata)
    new.type = type_ or f.type
    return new


def _declaring(record: type, key: str) -> type:
    """The class in `record`'s bases whose body declares `key` (where its help line is)."""
    return next(c for c in record.__mro__ if key in c.__dict__.get("__annotations__", {}))


MapConfig = _union()

