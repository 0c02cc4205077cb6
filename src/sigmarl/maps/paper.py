"""The paper's three hand-drawn test maps, shipped as center-line OSM files.

SigmaRL's authors drew their Intersection, On-Ramp and Roundabout in JOSM as center-line
ways (lane width 0.20 m). The files in `sigmarl/data/maps/` are written from the measured
facts (`paper_test_maps.json`: each lanelet's center line and successors, the evaluated
routes) by `write_paper_maps`, once, when the data changes:

    python -m sigmarl.maps.paper ../shared/reference/paper_test_maps.json src/sigmarl/data/maps

At run time the maps load like any user's OSM file (`conf/map/paper_*.yaml`, `kind: osm`,
`path: package:maps/<name>.osm`); the package never reads the JSON.
"""

from __future__ import annotations

import json
import sys
from importlib import resources
from pathlib import Path

import numpy as np

from sigmarl.errors import MapError
from sigmarl.maps.osm_write import save_centerline_osm

# Key in paper_test_maps.json -> the map's name in this project (conf/map/<name>.yaml).
PAPER_MAPS = {
    "intersection": "paper_intersection",
    "on_ramp": "paper_on_ramp",
    "roundabout": "paper_roundabout",
}
PACKAGE_PREFIX = "package:"  # map.path inside the package's data folder


def package_map_path(path: str) -> Path:
    """`package:maps/x.osm` -> the file inside sigmarl/data; other paths unchanged."""
    if not path.startswith(PACKAGE_PREFIX):
        return Path(path)
    rel = path[len(PACKAGE_PREFIX):]
    target = resources.files("sigmarl").joinpath("data", *rel.split("/"))
    if not target.is_file():
        raise MapError(f"map.path={path}: no such file in the sigmarl package ({target})")
    return Path(str(target))


def write_paper_maps(facts_json: str | Path, out_dir: str | Path) -> list[Path]:
    """Write one center-line OSM file per map of the facts file; returns the paths."""
    facts = json.loads(Path(facts_json).read_text(encoding="utf-8"))
    out = []
    for key, name in PAPER_MAPS.items():
        lanelets = facts["maps"][key]["lanelets"]
        centers = {int(lid): np.asarray(la["center"], dtype=np.float64) for lid, la in lanelets.items()}
        out.append(save_centerline_osm(dict(sorted(centers.items())), Path(out_dir) / f"{name}.osm"))
    return out


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit("usage: python -m sigmarl.maps.paper <paper_test_maps.json> <out_dir>")
    for p in write_paper_maps(sys.argv[1], sys.argv[2]):
        print(f"wrote {p}")
