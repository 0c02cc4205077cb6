"""Write SigmaRL's twelve later hand-drawn maps as project maps, from the measured facts.

The facts file (`sigmarl_more_maps.json`: per map each lanelet's center line and
successors, the lane width, the routes its authors listed, their agent count) becomes, per
map `<key>`:

* `src/sigmarl/data/maps/<key>.osm`: the center lines as SigmaRL-style OSM ways, the form
  the authors drew them in (loaded at run time like any user's file);
* `conf/map/<key>.yaml`: the map config, with the authors' routes;
* `conf/scenario/<key>.yaml`: the scenario, with the authors' agent count.

Run once, when the facts change; the written files are committed and the package never
reads the JSON. `--figure` then draws the twelve, as shipped, into one picture:

    python scripts/write_more_maps.py tests/data/sigmarl_more_maps.json
    python scripts/write_more_maps.py tests/data/sigmarl_more_maps.json --figure docs/maps/more_maps.png
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from sigmarl.maps.osm_write import save_centerline_osm

ROOT = Path(__file__).resolve().parents[1]


def map_yaml(key: str, facts: dict) -> str:
    routes = ", ".join("[" + ", ".join(map(str, r["lanelets"])) + "]" for r in facts["routes"])
    return (
        f"# SigmaRL's {key} (its authors' later hand-drawn maps, not in the paper): shipped as a\n"
        f"# center-line OSM file; {len(facts['lanelets'])} lanelets, lane width "
        f"{facts['lane_width']:.2f} m, the {len(facts['routes'])} routes its authors listed.\n"
        "defaults:\n"
        "  - base_map\n"
        "\n"
        f"name: {key}\n"
        "kind: osm\n"
        f"lane_width: {facts['lane_width']:.2f}\n"
        f"path: package:maps/{key}.osm\n"
        f"routes: [{routes}]\n"
    )


def scenario_yaml(key: str, facts: dict) -> str:
    return (
        f"# SigmaRL's {key}, with its authors' agent count (their later maps; not in the paper)\n"
        f"map: {key}\n"
        f"n_agents: {facts['n_agents']}\n"
        "paper: false\n"
    )


def write_more_maps(facts_json: str | Path, root: Path = ROOT) -> list[Path]:
    """Write every map of the facts file under `root`; returns the paths written."""
    facts = json.loads(Path(facts_json).read_text(encoding="utf-8"))["maps"]
    out = []
    for key, m in facts.items():
        centers = {int(i): np.asarray(la["center"], dtype=np.float64) for i, la in m["lanelets"].items()}
        out.append(save_centerline_osm(dict(sorted(centers.items())), root / "src/sigmarl/data/maps" / f"{key}.osm"))
        for folder, text in (("conf/map", map_yaml(key, m)), ("conf/scenario", scenario_yaml(key, m))):
            path = root / folder / f"{key}.yaml"
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(text, encoding="utf-8")
            out.append(path)
    return out


def draw_more_maps(facts_json: str | Path, out: str | Path) -> Path:
    """The shipped maps (conf/map/<key>.yaml) in a 4 x 3 grid, each with its routes."""
    from sigmarl.compose import compose_config
    from sigmarl.maps import load_map
    from sigmarl.maps.plot import save_map_grid

    facts = json.loads(Path(facts_json).read_text(encoding="utf-8"))["maps"]
    maps = []
    for key, m in facts.items():
        roadmap = load_map(compose_config([f"map={key}"]).map)
        maps.append((f"{key}: {len(roadmap.routes)} routes, lane {m['lane_width']:.2f} m, "
                     f"{m['n_agents']} agents", roadmap))
    return save_map_grid(out, maps, cols=4)


if __name__ == "__main__":
    args = sys.argv[1:]
    if len(args) == 3 and args[1] == "--figure":
        print(f"wrote {draw_more_maps(args[0], args[2])}")
    elif len(args) in (1, 2):
        for p in write_more_maps(args[0], Path(args[1]) if len(args) == 2 else ROOT):
            print(f"wrote {p}")
    else:
        sys.exit("usage: python scripts/write_more_maps.py <sigmarl_more_maps.json> "
                 "[<repository root> | --figure <out.png>]")
