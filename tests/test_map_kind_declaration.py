"""A kind of map is one record (`sigmarl.config.map`) and one builder. A toy kind, a plus-shaped
crossing whose arms' length is its own key, is added to a copy of the package by appending its
record to config/map.py and its builder to maps/builders.py, and nothing else. In that copy the
config key, its range and help line, the `kind` choice, the map's loading, its training run's
params and the fingerprint follow it, while every committed run keeps its fingerprint and
every committed row file its evaluation key."""

from __future__ import annotations

import filecmp
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "src" / "sigmarl"

UNION = "\n\n# The `map` group: every kind above in one record."
RECORD = '''

@map_kind("plus", builder="sigmarl.maps.builders:plus_map")
@dataclass
class PlusMap(LaneWidth):
    """A plus-shaped crossing of four equal arms."""

    plus_arm: float = ranged(0.9, lo=0, lo_open=True)
    """Plus: length in m of each of its four arms."""
'''

BUILDER = '''

def plus_map(cfg: MapConfig) -> RoadMap:
    """The plus-shaped crossing of a MapConfig (kind plus)."""
    return build_intersection(cfg.name or cfg.kind, float(cfg.lane_width), 4, [float(cfg.plus_arm)], 0.45)
'''

CHECK = '''
from pathlib import Path

import pandas as pd

from sigmarl.compose import compose_config
from sigmarl.config.help import describe
from sigmarl.errors import SigmarlError
from sigmarl.identity import fingerprint
from sigmarl.maps import load_map
from sigmarl.maps.builders import build_intersection
from sigmarl.readers import read_run_config
from sigmarl.tracking.training import training_params

import sigmarl
assert Path(sigmarl.__file__).parent == Path({package!r}), sigmarl.__file__  # the copy, not the checkout

base = ["tracking.enabled=false", "map=intersection"]
cfg = compose_config([*base, "map.kind=plus", "map.name=plus", "map.plus_arm=1.1"])
assert cfg.map.plus_arm == 1.1
# the builder the record names builds it: the intersection builder's map of the same arms
made, expected = load_map(cfg.map), build_intersection("plus", 0.2, 4, [1.1], 0.45)
assert made.name == "plus" and len(made.lanelets) == len(expected.lanelets) and len(made.routes) == len(expected.routes)
# its key is checked against the range on its field, and has its help line
try:
    compose_config([*base, "map.kind=plus", "map.plus_arm=-1"])
    raise AssertionError("a negative arm passed")
except SigmarlError as e:
    assert "map.plus_arm must be positive" in str(e), e
assert "Plus: length in m of each of its four arms." in describe("map.plus_arm")
assert "plus" in describe("map.kind")
# a training run records the plus map's own keys, and an intersection's run does not
assert training_params(cfg)["map.plus_arm"] == "1.1"
assert "map.plus_arm" not in training_params(compose_config(base))
# the fingerprint: the key counts away from its default, and leaves every earlier run alone
assert fingerprint(cfg) != fingerprint(compose_config([*base, "map.kind=plus", "map.name=plus"]))
assert fingerprint(compose_config(base)) == fingerprint(compose_config([*base, "map.plus_arm=0.9"]))
recorded = 0
for rows in sorted(Path({root!r}).glob("results/*/*/seed*/evaluation_rows.csv")):
    if "fingerprint" not in pd.read_csv(rows, nrows=0).columns:
        continue
    run = read_run_config(rows.parent / "config.yaml")  # its map keys: every kind's but plus
    assert run.map.plus_arm == 0.9
    assert set(pd.read_csv(rows, usecols=["fingerprint"], dtype=str)["fingerprint"]) == {{fingerprint(run)}}, rows
    recorded += 1
# and every committed row file's evaluation key: its study's protocol, else its run's, as recorded
import json
from sigmarl.eval_key import eval_key
studies = {{(Path({root!r}) / c.runs_root).resolve(): eval_key(c.eval) for c in
           (compose_config([f"study={{s.stem}}"]) for s in sorted(Path({root!r}, "conf", "study").glob("*.yaml")))}}
for rows in sorted(Path({root!r}, "results").rglob("evaluation_rows.csv")):
    config = rows.parent / "config.yaml"
    now = studies.get(rows.parents[2].resolve()) or (
        eval_key(read_run_config(config).eval) if config.is_file() else eval_key(compose_config([]).eval))
    assert now == json.loads((rows.parent / "evaluation.json").read_text())["eval_key"], rows
print("toy map kind followed", recorded)
'''


def _changed(a: Path, b: Path) -> list[str]:
    """The files of the two trees that differ or exist in one only, relative paths."""
    cmp, out = filecmp.dircmp(a, b, ignore=["__pycache__"]), []
    out += [str(Path(a.name, n)) for n in cmp.diff_files + cmp.left_only + cmp.right_only]
    for sub in cmp.subdirs:
        out += [str(Path(a.name, p)) for p in _changed(a / sub, b / sub)]
    return out


def test_a_kind_of_map_is_its_record_and_its_builder(tmp_path):
    copy = tmp_path / "sigmarl"
    shutil.copytree(PACKAGE, copy, ignore=shutil.ignore_patterns("__pycache__", "data"))
    (copy / "data").symlink_to(PACKAGE / "data")  # the CPM map's file and the paper's policies, unchanged
    records = copy / "config" / "map.py"  # the record beside the other kinds', before their union
    text = records.read_text()
    assert text.count(UNION) == 1
    records.write_text(text.replace(UNION, RECORD + UNION))
    with (copy / "maps" / "builders.py").open("a") as f:
        f.write(BUILDER)
    changed = sorted(_changed(PACKAGE, copy))
    assert changed == ["sigmarl/config/map.py", "sigmarl/maps/builders.py"], changed
    script = tmp_path / "check.py"
    script.write_text(textwrap.dedent(CHECK.format(package=str(copy), root=str(ROOT))))
    env = {**os.environ, "PYTHONPATH": str(tmp_path)}
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, cwd=tmp_path, env=env,
                          timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    assert "toy map kind followed" in done.stdout and int(done.stdout.split()[-1]) > 0
