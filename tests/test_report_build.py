"""build_report end to end on hand-made rows: files, shape, errors, figures."""

from __future__ import annotations

import pandas as pd
import pytest

from sigmarl.errors import SigmarlError
from sigmarl.report import build_report
from tests.test_report_tables import MODELS, SCENARIOS, hand_rows


def test_writes_the_table_files(tmp_path):
    report = build_report(hand_rows(), out_dir=tmp_path, latex=True, figures=False)
    assert {p.name for p in tmp_path.iterdir()} == {
        "table.md", "table.csv", "summary.csv", "composite_scores.csv", "table.tex",
    }  # fmt: skip
    assert report.paths["markdown"].read_text() == report.markdown
    assert report.table.values.shape == (len(SCENARIOS) * 6, len(MODELS))
    header = report.markdown.splitlines()[0]
    assert header == "| Scenario | Metric | " + " | ".join(MODELS) + " |"
    cs = pd.read_csv(report.paths["composite"]).set_index(["scenario", "model"])["CS"]
    assert cs[("CPM", "M2")] == pytest.approx(
        -0.6025, abs=1e-4
    )  # hand value, see test_report_tables
    assert "Mean over 3 simulations per cell" in report.markdown


def test_paper_comparison_and_trim_notes(tmp_path):
    report = build_report(
        hand_rows(), ["M0", "M2"], out_dir=tmp_path, compare_paper=True, figures=False
    )
    assert "(0.04)" in report.markdown  # paper CPM CR_AA of M0
    assert any("not trimmed" in n for n in report.notes)
    assert any("not comparable" in n for n in report.notes)  # CS over M0, M2 only
    trimmed = build_report(
        hand_rows(), out_dir=tmp_path, trim=True, compare_paper=True, figures=False
    )
    assert not any("not trimmed" in n or "not comparable" in n for n in trimmed.notes)


def test_all_zero_collisions_still_reports(tmp_path):
    rows = hand_rows().assign(CR_AA=0.0, CR_AL=0.0, CR_total=0.0)
    report = build_report(rows, out_dir=tmp_path, figures=False)
    assert report.table.values.xs("CS", level="metric").isna().all().all()
    assert "composite score undefined: no model collided" in report.markdown


def test_empty_input_is_a_clear_error(tmp_path):
    with pytest.raises(SigmarlError, match="no finished evaluation runs"):
        build_report(hand_rows().iloc[0:0], out_dir=tmp_path)
    assert not any(tmp_path.iterdir())


def test_figures(tmp_path):
    curves = pd.DataFrame(
        [{"model": m, "seed": s, "iteration": i, "reward": i * 0.1 + s}
         for m in MODELS[:2] for s in (0, 1) for i in range(5)]
    )  # fmt: skip
    report = build_report(hand_rows(), out_dir=tmp_path, curves=curves)
    for key in ("distributions", "training_curves"):
        assert report.paths[key].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
