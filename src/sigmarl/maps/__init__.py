"""Road maps: the model, the CPM Lab loader, procedural builders, OSM files, and a map's config
by name (`conf/map/<name>.yaml`) or by the scenario that runs on it."""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

from sigmarl.errors import MapError, SigmarlError
from sigmarl.maps.model import Lanelet, RoadMap, Route

if TYPE_CHECKING:
    from sigmarl.config import MapConfig

__all__ = ["Lanelet", "MapError", "RoadMap", "Route", "load_map", "map_config", "scenario_map_config"]


def load_map(cfg: MapConfig) -> RoadMap:
    """Build the RoadMap a `MapConfig` describes, with the builder its kind's record names
    (`sigmarl.config.map`), imported only for a map of that kind."""
    # lazy: the map model (every environment module imports it) needs no config machinery
    from sigmarl.config.map import kind_of

    module, _, function = kind_of(cfg).builder.partition(":")
    return getattr(importlib.import_module(module), function)(cfg)


def osm_map(cfg: MapConfig) -> RoadMap:
    """The map of an OSM file (kind osm); `package:maps/x.osm` is a map shipped with sigmarl."""
    from sigmarl.maps.osm import load_osm
    from sigmarl.maps.paper import package_map_path

    return load_osm(package_map_path(cfg.path), lane_width=cfg.lane_width, routes=list(cfg.routes) or None,
                    name=cfg.name)


def map_config(name: str) -> MapConfig:
    """conf/map/<name>.yaml (or a user's, see `sigmarl.paths`) on the MapConfig schema, without
    Hydra's global state, so that code running inside a Hydra job (a sweep's evaluation) can
    read it. The one reader of a map config file outside Hydra's composition."""
    # lazy: the map model (every environment module imports it) needs no config machinery
    from omegaconf import OmegaConf
    from omegaconf.errors import OmegaConfBaseException

    from sigmarl.config import MapConfig
    from sigmarl.paths import config_files
    from sigmarl.readers import read_yaml

    files = config_files("map")
    if name not in files:
        raise SigmarlError(f"no map config {name!r} (conf/map/{name}.yaml); known maps: {', '.join(sorted(files))}")
    values = read_yaml(files[name], "a map config")
    if not isinstance(values, dict):
        raise SigmarlError(f"{files[name]}: a map config holds keys and values; correct the file")
    values.pop("defaults", None)
    try:
        return OmegaConf.to_object(OmegaConf.merge(OmegaConf.structured(MapConfig), values))
    except OmegaConfBaseException as e:
        raise SigmarlError(f"{files[name]}: {str(e).splitlines()[0]}") from e


def scenario_map_config(name: str) -> MapConfig:
    """The map config of an evaluation scenario (conf/scenario/<name>.yaml names it)."""
    from sigmarl.scenarios import scenario

    return map_config(scenario(name).map)
