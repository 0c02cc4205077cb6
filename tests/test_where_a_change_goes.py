"""The architecture page's "Where a change goes" table is held to the code: every file it names
exists, every name it places in a file is there, and the rows for a new observation strategy, a
new kind of map and a new metric name the source files their toy declarations touch
(tests/test_strategy_declaration.py, tests/test_map_kind_declaration.py)."""

from __future__ import annotations

import dataclasses
import importlib
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "architecture.md"
PATH = re.compile(r"`((?:src|conf|tests|scripts|docs)/[^`]*)`")
PLACED = re.compile(r"`([A-Za-z_][A-Za-z0-9_]*)`[^`(]{0,20}\(`(src/[^`]+\.py)`")


def _rows() -> dict[str, str]:
    """change (its bold words) -> the row's files cell."""
    text = PAGE.read_text(encoding="utf-8").split("## Where a change goes", 1)[1].split("\n## ", 1)[0]
    rows = {}
    for line in text.splitlines():
        if line.startswith("| ") and "**" in line:
            change, files = line[2:].split(" | ", 1)
            rows[re.search(r"\*\*(.+?)\*\*", change).group(1)] = files
    return rows


def _source_files(cell: str) -> set[str]:
    return {p for p in PATH.findall(cell) if p.startswith("src/") and p.endswith(".py")}


def test_every_file_the_table_names_exists():
    rows = _rows()
    assert {"metric", "kind of map", "observation strategy"} <= set(rows)
    missing = []
    for change, cell in rows.items():
        for path in PATH.findall(cell):
            pattern = re.sub(r"<[^>]+>", "*", path)
            if not (list(ROOT.glob(pattern)) if "*" in pattern else (ROOT / pattern).exists()):
                missing.append(f"{change}: {path}")
    assert not missing, "the table names files that are not there: " + ", ".join(missing)


def test_every_name_the_table_places_in_a_file_is_there():
    wrong = [f"{name} in {path}" for cell in _rows().values() for name, path in PLACED.findall(cell)
             if not re.search(rf"\b{name}\b", (ROOT / path).read_text(encoding="utf-8"))]
    assert not wrong, "the table places names where they are not: " + ", ".join(wrong)
    assert ("STRATEGIES", "src/sigmarl/ablation.py") in PLACED.findall(_rows()["observation strategy"])


def test_the_three_extensions_name_the_files_their_toys_touch():
    rows = _rows()
    # a strategy: its declaration (and a preset, a test); the toy appends to ablation.STRATEGIES
    assert _source_files(rows["observation strategy"]) == {"src/sigmarl/ablation.py"}
    assert "tests/test_strategy_declaration.py" in rows["observation strategy"]
    # a kind of map: the two files the toy kind is written into
    assert _source_files(rows["kind of map"]) == {"src/sigmarl/config/map.py", "src/sigmarl/maps/builders.py"}
    assert "tests/test_map_kind_declaration.py" in rows["kind of map"]
    # a metric: its record, and its measurement in the evaluation
    assert "src/sigmarl/metrics.py" in _source_files(rows["metric"])
    assert all(p == "src/sigmarl/metrics.py" or p.startswith("src/sigmarl/evaluation/")
               for p in _source_files(rows["metric"]))


def test_every_kind_of_map_names_a_builder_that_is_there():
    from sigmarl.config.map import MAP_KINDS, MapConfig

    assert set(MAP_KINDS) == {"cpm", "intersection", "roundabout", "on_ramp", "osm"}
    for kind in MAP_KINDS.values():
        module, _, function = kind.builder.partition(":")
        assert callable(getattr(importlib.import_module(module), function)), kind.builder
        assert set(kind.keys) <= {f.name for f in dataclasses.fields(MapConfig)}
