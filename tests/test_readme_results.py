"""The README's results blocks are what the committed study folder rebuilds, byte for byte."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _script():
    spec = importlib.util.spec_from_file_location("readme_results", ROOT / "scripts" / "readme_results.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.slow
def test_readme_results_are_the_rebuilt_report(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # tracking is off; nothing may land in the checkout
    script = _script()
    text = script.README.read_text(encoding="utf-8")
    rebuilt = script.report_files()
    assert set(rebuilt) == {"results-table", "results-statistics", "results-training", "results-verdicts", "results-curves",
                            "results-seeds",
                            "generalisation-matrix", "generalisation-verdicts", "rules-verdicts"}
    for name, content in rebuilt.items():
        start, end = script.readme_block(text, name)
        assert text[start:end] == content, (
            f"README's {name} block differs from the report of its committed folders: "
            "run `python scripts/readme_results.py`")
