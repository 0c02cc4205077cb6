"""The README's results table is what the committed study folder rebuilds, byte for byte."""

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
def test_readme_table_is_the_rebuilt_table(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # tracking is off; nothing may land in the checkout
    script = _script()
    text = script.README.read_text(encoding="utf-8")
    start, end = script.readme_table(text)
    assert text[start:end] == script.report_table(), (
        "README's results table differs from `sigmarl report --from results/paper-budget`: "
        "run `python scripts/readme_results.py`")
