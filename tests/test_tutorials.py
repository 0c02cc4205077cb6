"""Each tutorial of the documentation, run as written (tests/tutorials.py) at a smoke budget,
so that a tutorial cannot rot: its files written, its commands run in a fresh folder, and what
it says they make checked."""

from __future__ import annotations

import json

import pandas as pd
import pytest
from PIL import Image
from tutorials import run_tutorial

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


def test_a_map_of_ones_own(tmp_path):
    from sigmarl.maps.osm import load_osm

    run_tutorial("tutorials/osm-map.md", tmp_path)
    assert (tmp_path / "my_map.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    road = load_osm(tmp_path / "my_map.osm")
    assert sorted(r.lanelet_ids for r in road.routes) == [(1, 2), (1, 3), (4,)]  # what the page says
    runs = list((tmp_path / "runs").rglob("final.pt"))
    assert len(runs) == 1, runs


def test_a_tracker_of_ones_own(tmp_path):
    run_tutorial("tutorials/own-tracker.md", tmp_path)
    records = [json.loads(line) for line in (tmp_path / "records.jsonl").read_text().splitlines()]
    assert {"run": "M0-0", "status": "FINISHED"} in records
    assert [r for r in records if "evaluation" in r] and [r for r in records if "report" in r]
    assert not list(tmp_path.rglob("mlflow.db"))
