"""Each tutorial of the documentation, run as written (tests/tutorials.py) at a smoke budget,
so that a tutorial cannot rot: its files written, its commands run in a fresh folder, and what
it says they make checked."""

from __future__ import annotations

import json

import pandas as pd
import pytest
from PIL import Image
from tutorials import run_tutorial

from sigmarl.errors import SigmarlError

pytestmark = pytest.mark.slow


def _table(path):
    """The model columns of a report's table.csv (after its scenario, metric, unit and source)."""
    return [c for c in pd.read_csv(path).columns if c not in ("scenario", "metric", "unit", "source")]


def test_own_ablation(tmp_path):
    run_tutorial("tutorials/own-ablation.md", tmp_path)
    for label in ("W256", "W64"):
        for seed in (0, 1):
            assert (tmp_path / "runs" / "narrow" / label / f"seed{seed}" / "evaluated.txt").exists()
    table = pd.read_csv(tmp_path / "reports" / "narrow" / "table.csv")
    assert _table(tmp_path / "reports" / "narrow" / "table.csv") == ["W256", "W64"]
    assert set(table["scenario"].dropna()) >= {"CPM", "Intersection", "My-Roundabout"}
    rows = pd.read_csv(tmp_path / "runs" / "narrow" / "W64" / "seed0" / "evaluation_rows.csv")
    assert set(rows["scenario"]) == {"CPM", "Intersection", "My-Roundabout"}
    for k in (0, 1):
        assert Image.open(tmp_path / "reports" / "animations" / f"W64_seed1_My-Roundabout_sim{k}.gif").n_frames == 100


def test_plan_and_seeds_auto(tmp_path):
    def plan_writes_nothing(i, done):
        if i == 1:  # the plan: a table on the terminal, no report folder
            assert "M4" in done.stdout and "needed" in done.stdout
            assert not (tmp_path / "reports").exists() or not any((tmp_path / "reports").iterdir())

    assert len(run_tutorial("tutorials/plan-and-seeds.md", tmp_path, after=plan_writes_nothing)) == 4
    record = json.loads((tmp_path / "runs" / "sigmarl-quick" / "seeds_auto.json").read_text())
    assert record["n_start"] == 2 and record["max_seeds"] == 4 and record["looks"]
    for label, seeds in record["seeds"].items():
        assert label in ("M0", "M4") and 2 <= len(seeds) <= 4
        for seed in seeds:
            assert (tmp_path / "runs" / "sigmarl-quick" / label / f"seed{seed}" / "evaluated.txt").exists()
    assert (tmp_path / "reports" / "sigmarl-quick_models-M0+M4" / "verdicts.md").exists()


def test_cluster_on_one_machine(tmp_path):
    pytest.importorskip("hydra_plugins.hydra_submitit_launcher")
    run_tutorial("tutorials/cluster.md", tmp_path)
    for label in ("M0", "M4"):
        assert (tmp_path / "runs" / "sigmarl-quick" / label / "seed0" / "evaluated.txt").exists()
    assert list((tmp_path / "multirun").rglob("*submitit*")) or list((tmp_path / "multirun").rglob(".submitit"))
    assert _table(tmp_path / "reports" / "sigmarl-quick_models-M0+M4" / "table.csv") == ["M0", "M4"]


def test_a_map_of_ones_own(tmp_path, monkeypatch):
    """The OSM tutorial as written: the file, its lane width checked, its map config and scenario
    in a config folder, listed by --info, trained on, evaluated and watched."""
    from sigmarl.maps import load_map, map_config
    from sigmarl.maps.osm import load_osm
    from sigmarl.paths import CONFIG_PATH

    done = run_tutorial("tutorials/osm-map.md", tmp_path)
    shown = done[0].stdout  # maps show my_map.osm ... map.lane_width=0.25
    assert "4 beside 5 (0.250 m apart, 1.00 widths)" in shown  # what the page says it prints
    assert (tmp_path / "my_map.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    road = load_osm(tmp_path / "my_map.osm", lane_width=0.25)
    assert sorted(r.lanelet_ids for r in road.routes) == [(1, 2), (1, 3), (4,), (5,)]  # what the page says
    # the page's other widths: 1.25 widths apart at 0.20 m, not side by side at 0.15 m
    assert load_osm(tmp_path / "my_map.osm", lane_width=0.20).lanelets[5].beside_left == [4]
    assert load_osm(tmp_path / "my_map.osm", lane_width=0.15).lanelets[5].beside_left == []
    info = done[1].stdout
    assert next(line for line in info.splitlines() if line.startswith("  map ")).endswith("; [1] my_map")
    assert info.rstrip().count("[1] My-Map") == 1
    runs = list((tmp_path / "runs" / "my_map").rglob("final.pt"))
    assert len(runs) == 1, runs
    written = list((tmp_path / "runs" / "my_map" / "M0" / "seed0").glob("evaluation_rows*.csv"))
    assert [f.name.startswith("evaluation_rows-") for f in written] == [True]  # beside the study's, as the page says
    rows = pd.read_csv(written[0])
    assert set(rows["scenario"]) == {"My-Map"} and len(rows) == 4
    assert Image.open(tmp_path / "reports" / "animations" / "M0_seed0_My-Map_sim0.gif").n_frames == 100
    # the relative path is read from the folder the command runs in, not from the config's
    monkeypatch.setenv(CONFIG_PATH, str(tmp_path / "my_conf"))
    cfg = map_config("my_map")
    assert cfg.path == "my_map.osm" and cfg.lane_width == 0.25 and cfg.n_arms == 4  # a schema default
    monkeypatch.chdir(tmp_path)
    assert len(load_map(cfg).lanelets) == 5
    monkeypatch.chdir(tmp_path / "my_conf")
    with pytest.raises(SigmarlError, match="my_map.osm"):
        load_map(cfg)


def test_a_tracker_of_ones_own(tmp_path):
    run_tutorial("tutorials/own-tracker.md", tmp_path)
    records = [json.loads(line) for line in (tmp_path / "records.jsonl").read_text().splitlines()]
    assert {"run": "M0-0", "status": "FINISHED"} in records
    assert [r for r in records if "evaluation" in r] and [r for r in records if "report" in r]
    assert not list(tmp_path.rglob("mlflow.db"))
