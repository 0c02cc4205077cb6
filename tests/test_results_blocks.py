"""The generated results blocks of the README and the results pages are what the committed
study folders rebuild, byte for byte."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _script():
    spec = importlib.util.spec_from_file_location("results_blocks", ROOT / "scripts" / "results_blocks.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_every_page_holds_its_markers_once():
    script = _script()
    assert {"README.md", "docs/results/paper-study.md", "docs/results/paper-study-details.md"} <= set(script.pages())
    assert script.blocks_of_page("README.md") == ["results-table"]  # the README keeps Table I only
    for page in script.pages():
        text = (ROOT / page).read_text(encoding="utf-8")
        for name in script.blocks_of_page(page):
            assert text.count(f"<!-- {name} -->\n") == 1 and text.count(f"<!-- /{name} -->\n") == 1, (page, name)
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    stray = [name for name in script.BLOCKS if name != "results-table" and f"<!-- {name} -->" in readme]
    assert not stray, f"README.md holds blocks that belong in the docs: {stray}"


@pytest.mark.slow
def test_results_blocks_are_the_rebuilt_report(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # tracking is off; nothing may land in the checkout
    script = _script()
    rebuilt = script.report_files()
    assert set(rebuilt) == {"results-table", "results-replication", "results-findings", "results-statistics", "results-training", "results-verdicts",
                            "results-curves", "results-seeds", "results-paper-policies", "rule-based-matrix",
                            "generalisation-matrix", "generalisation-verdicts", "rules-verdicts"}
    for page in script.pages():
        text = (ROOT / page).read_text(encoding="utf-8")
        for name in script.blocks_of_page(page):
            start, end = script.block(text, name, page)
            assert text[start:end] == rebuilt[name], (
                f"{page}'s {name} block differs from the report of its committed folders: "
                "run `python scripts/results_blocks.py`")
