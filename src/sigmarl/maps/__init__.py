"""Road maps: the model, the CPM Lab loader, procedural builders, OSM files."""

from __future__ import annotations

from typing import TYPE_CHECKING

from sigmarl.errors import MapError
from sigmarl.maps.model import Lanelet, RoadMap, Route

if TYPE_CHECKING:
    from sigmarl.config import MapConfig

__all__ = ["Lanelet", "MapError", "RoadMap", "Route", "load_map"]


def load_map(cfg: MapConfig) -> RoadMap:
    """Build the RoadMap a `MapConfig` describes."""
    kind = cfg.kind
    if kind == "cpm":
        # lazy: each loader (XML, geometry) only for its kind of map
        from sigmarl.maps.cpm import load_cpm

        return load_cpm(cfg.route_set)
    if kind in ("intersection", "on_ramp", "roundabout"):
        from sigmarl.maps import builders

        return builders.build(cfg)
    if kind == "osm":
        from sigmarl.maps.osm import load_osm
        from sigmarl.maps.paper import package_map_path

        if not cfg.path:
            raise MapError("map.kind=osm needs map.path=<file.osm>")
        path = package_map_path(cfg.path)  # `package:maps/x.osm`: a map shipped with sigmarl
        return load_osm(path, lane_width=cfg.lane_width, routes=list(cfg.routes) or None, name=cfg.name)
    raise MapError(f"unknown map kind {kind!r}; choose cpm, intersection, on_ramp, roundabout or osm")
