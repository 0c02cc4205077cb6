"""`sigmarl sweep --check`: a study checked before it trains. A broken OSM map behind a shipped
scenario (which planning alone does not load) is refused in one line; a good study is listed
with its estimated costs; either way the folder it runs in is left exactly as it was."""

from __future__ import annotations

import time
from pathlib import Path

from sigmarl.cli import main

STUDY = """# @package _global_
defaults:
  - quick
study:
  name: mine
  variants:
    M0: [obs=full]
tracking:
  experiment: mine
"""
# the user's own interchange_1, its second route not connected: a shipped scenario's map (the
# plan loads only the maps of a user's own scenarios), so a plain sweep would meet it at evaluation
BROKEN_MAP = """defaults:
  - base_map
name: interchange_1
kind: osm
lane_width: 0.30
path: package:maps/interchange_1.osm
routes: [[1, 2, 3], [1, 5]]
"""


def _tree(root: Path) -> dict[str, tuple[int, int]]:
    """Every path below `root` with its size and modification time."""
    return {str(p.relative_to(root)): (p.stat().st_size, p.stat().st_mtime_ns) for p in root.rglob("*")}


def _folder(tmp_path: Path, monkeypatch, broken: bool) -> Path:
    conf = tmp_path / "my_conf"
    (conf / "study").mkdir(parents=True)
    (conf / "study" / "mine.yaml").write_text(STUDY)
    if broken:
        (conf / "map").mkdir()
        (conf / "map" / "interchange_1.yaml").write_text(BROKEN_MAP)
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("SIGMARL_CONFIG_PATH", raising=False)
    return conf


def test_a_broken_osm_scenario_is_refused_in_one_line_writing_nothing(tmp_path, monkeypatch, capsys):
    conf = _folder(tmp_path, monkeypatch, broken=True)
    before = _tree(tmp_path)
    start = time.process_time()
    rc = main(["--config-dir", str(conf), "sweep", "--check", "study=mine", "eval.scenarios=[interchange_1]"])
    spent = time.process_time() - start
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2
    assert len(err) == 1 and "interchange_1" in err[0] and "not connected" in err[0], err
    assert spent < 60  # CPU seconds: the map fails as it loads, before any training set-up
    assert _tree(tmp_path) == before  # no run folder, plan, Hydra folder or MLflow store


def test_a_good_study_is_listed_with_its_costs_writing_nothing(tmp_path, monkeypatch, capsys):
    conf = _folder(tmp_path, monkeypatch, broken=False)
    before = _tree(tmp_path)
    rc = main(["--config-dir", str(conf), "sweep", "--check", "study=mine", "models=[M0]", "seeds=[0,1]",
               "eval.scenarios=[Intersection]", "eval.n_sims=2"])
    out = capsys.readouterr().out
    assert rc == 0, out
    assert "nothing trained or written" in out
    rows = [line.split() for line in out.splitlines() if line.startswith("  M0/seed")]
    assert [r[0] for r in rows] == ["M0/seed0", "M0/seed1"]
    assert all(r[2] == "s" and float(r[1]) > 0 for r in rows), rows  # a measured training time
    assert "memory: about" in out and "source: CPU time measured here on" in out
    assert _tree(tmp_path) == before
