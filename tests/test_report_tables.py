"""Table I on hand-made data: layout, bold best values, Markdown, LaTeX, CSV, build_report."""

from __future__ import annotations

import re

import pandas as pd
import pytest

from sigmarl.errors import SigmarlError
from sigmarl.report import BuildOptions, build_report
from sigmarl.report.cells import aggregate, composite_scores
from sigmarl.report.tables import build_table, paper_values, to_csv_frame, to_latex, to_markdown

MODELS = ["M0", "M1", "M2", "M3", "M4", "M5"]
SCENARIOS = ["CPM", "Intersection", "On-Ramp", "Roundabout"]
# Per model, designed so that each row has one known best (percent for CR):
CR_AA = [0.5, 0.2, 0.3, 0.4, 0.6, 0.7]  # best M1
CR_AL = [0.3, 0.4, 0.1, 0.5, 0.6, 0.7]  # best M2; CR_total 0.8 0.6 0.4 0.9 1.2 1.4 -> M2
CD = [2.0, 3.0, 2.5, 1.5, 2.2, 2.8]  # best M3
AS = [0.60, 0.50, 0.55, 0.58, 0.70, 0.65]  # best M4
# CS by hand (means CR 5.3/6, CD 14/6, AS 3.58/6):
# -0.7572 -1.1270 -0.6025 -0.6897 -1.1282 -1.6955 -> best M2.
CS = [-0.7572, -1.1270, -0.6025, -0.6897, -1.1282, -1.6955]
BEST = {"CR_AA": "M1", "CR_AL": "M2", "CR_total": "M2", "CD": "M3", "AS": "M4", "CS": "M2"}


def hand_rows(models=MODELS, collide_in_roundabout=True) -> pd.DataFrame:
    """Three simulations per cell at value - d, value, value + d: means are the values."""
    recs = []
    for scenario in SCENARIOS:
        for i, model in enumerate(models):
            for sim, d in enumerate([-0.01, 0.0, 0.01]):
                aa, al = CR_AA[i] / 100, CR_AL[i] / 100
                if scenario == "Roundabout" and not collide_in_roundabout:
                    aa = al = 0.0
                recs.append(
                    {"model": model, "obs": "x", "seed": 0, "scenario": scenario, "simulation": sim,
                     "CR_AA": aa, "CR_AL": al, "CR_total": aa + al, "CD": CD[i] + d, "AS": AS[i] + d}
                )  # fmt: skip
    return pd.DataFrame(recs)


def make_table(rows, models=MODELS, paper=None):
    summary = aggregate(rows, models)
    return build_table(summary, composite_scores(summary), models, paper)


def body(markdown: str) -> list[list[str]]:
    lines = [ln for ln in markdown.splitlines() if ln.startswith("|")][2:]
    return [[c.strip() for c in ln.strip("|").split("|")] for ln in lines]


def test_shape_and_values():
    table = make_table(hand_rows())
    assert table.values.shape == (24, 6) and table.models == MODELS
    assert table.scenarios == SCENARIOS
    metrics = list(table.values.loc["CPM"].index)
    assert metrics == ["CR_AA", "CR_AL", "CR_total", "CD", "AS", "CS"]
    assert table.values.loc[("CPM", "CR_total")].tolist() == pytest.approx(
        [0.8, 0.6, 0.4, 0.9, 1.2, 1.4]
    )
    assert table.values.loc[("CPM", "CS")].tolist() == pytest.approx(CS, abs=1e-4)


def test_markdown_bolds_the_best_cell_of_each_row():
    rows = body(to_markdown(make_table(hand_rows(collide_in_roundabout=False))))
    assert len(rows) == 24 and all(len(r) == 8 for r in rows)
    assert [r[0] for r in rows if r[0]] == SCENARIOS  # scenario named once per group
    for k, row in enumerate(rows):
        scenario, metric = SCENARIOS[k // 6], row[1].split(" ")[0]
        bold = [MODELS[j] for j, cell in enumerate(row[2:]) if cell.startswith("**")]
        if scenario == "Roundabout" and metric.startswith("CR"):
            assert bold == [], row  # every model at 0 %: a tie, no best
        elif scenario == "Roundabout" and metric == "CS":
            assert bold == [] and set(row[2:]) == {"–"}, row  # undefined
        else:
            assert bold == [BEST[metric]], row
    assert rows[0][:4] == ["CPM", "CR_AA (%)", "0.50", "**0.20**"]


def test_undefined_composite_score_is_explained():
    summary = aggregate(hand_rows(collide_in_roundabout=False))
    notes = composite_scores(summary).set_index(["scenario", "model"])["note"]
    assert "no model collided" in notes[("Roundabout", "M0")]
    assert notes[("CPM", "M0")] == ""


def test_ties_as_printed_are_all_bold():
    rows = hand_rows()
    rows.loc[rows.model == "M5", "AS"] = rows.loc[rows.model == "M4", "AS"].to_numpy() + 0.001
    markdown_rows = body(to_markdown(make_table(rows)))
    as_row = next(r for r in markdown_rows if r[1] == "AS (m/s)")
    assert as_row[6:8] == ["**0.70**", "**0.70**"]  # M4 0.700, M5 0.701: equal as printed


def test_ci_and_paper_in_cells():
    table = make_table(hand_rows(), paper=paper_values(MODELS))
    rows = body(to_markdown(table, ci=True))
    # CD of M0: 1.99, 2.00, 2.01 (one seed): a resample of all three at either end has
    # probability 1/27 > 2.5%, so the interval is [1.99, 2.01]; the paper's CPM M0 CD is
    # 2.331 real cm.
    cd = next(r for r in rows if r[1] == "CD (cm)")
    assert cd[2] == "2.00 [1.99, 2.01] (2.33)"
    assert rows[0][2] == "0.50 [0.50, 0.50] (0.04)"  # identical in all simulations: no width


def test_latex_booktabs_and_escaping():
    models = ["M0", "my_model", "M2"]
    rows = hand_rows(models=models)
    tex = to_latex(make_table(rows, models), ci=True)
    for rule in (r"\toprule", r"\midrule", r"\bottomrule", r"\begin{tabular}{lrrr}"):
        assert rule in tex
    assert "my\\_model" in tex and "CR\\_total (\\%)" in tex
    assert r"\textit{On-Ramp}" in tex
    body_lines = [ln for ln in tex.splitlines() if not ln.startswith("%")]
    text = "\n".join(body_lines)
    assert not re.search(r"(?<!\\)[_%#]", text), "unescaped special character"
    assert text.count("{") == text.count("}")
    # CR_AA of M0, my_model, M2 = 0.5, 0.2, 0.3 %: my_model is bold; minus signs typeset.
    cr_aa = next(ln for ln in body_lines if ln.startswith("CR\\_AA"))
    assert cr_aa.split(" & ")[2].startswith(r"\textbf{0.20")
    cs = next(ln for ln in body_lines if ln.startswith("CS "))
    assert "$-$" in cs and " -" not in cs
    rows_with_cells = [ln for ln in body_lines if " & " in ln]
    assert len(rows_with_cells) == 1 + 24  # header + 4 scenarios x 6 metrics
    assert all(ln.endswith("\\\\") and ln.count("&") == len(models) for ln in rows_with_cells)


def test_csv_round_trips_with_pandas(tmp_path):
    table = make_table(hand_rows(), paper=paper_values(MODELS))
    frame = to_csv_frame(table)
    frame.to_csv(tmp_path / "table.csv", index=False)
    back = pd.read_csv(tmp_path / "table.csv")
    pd.testing.assert_frame_equal(back, frame, check_dtype=False)
    assert list(back.columns) == ["scenario", "metric", "unit", "source", *MODELS]
    ours = back[back.source == "ours"].set_index(["scenario", "metric"])
    paper = back[back.source == "paper"].set_index(["scenario", "metric"])
    assert ours.shape[0] == paper.shape[0] == 24
    assert ours.loc[("CPM", "CR_AA"), "M1"] == pytest.approx(0.2)  # percent, unrounded
    assert paper.loc[("CPM", "CS"), "M4"] == pytest.approx(0.28)
    assert ours.loc[("CPM", "CR_AA"), "unit"] == "percent"


# build_report end to end on the same hand-made rows: files, shape, errors, figures.


def test_writes_the_table_files(tmp_path):
    report = build_report(hand_rows(), BuildOptions(out_dir=tmp_path, latex=True, figures=False))
    assert {p.name for p in tmp_path.iterdir()} == {
        "table.md", "table.csv", "summary.csv", "composite_scores.csv", "table.tex",
        "improvement.csv", "aggregate_scores.csv", "statistics.md", "verdicts.md", "verdicts.csv",
        "marl_eval.json", "marl_eval_intervals.json", "matrix.md", "seeds.md", "seeds.csv", "findings.md",
        "improvement_overall.csv",
    }  # fmt: skip
    assert report.paths["markdown"].read_text() == report.markdown
    matrix = report.paths["matrix"].read_text().splitlines()
    assert matrix[2] == "| Scenario | " + " | ".join(MODELS) + " |" and len(matrix) == 4 + len(SCENARIOS) + 5 + len(SCENARIOS)
    assert matrix[4 + len(SCENARIOS) + 1] == "M0: how it collides, how it drives:"
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
        hand_rows(), BuildOptions(out_dir=tmp_path, models=["M0", "M2"], compare_paper=True, figures=False)
    )
    assert "(0.04)" in report.markdown  # paper CPM CR_AA of M0
    assert any("not trimmed" in n for n in report.notes)
    assert any("not comparable" in n for n in report.notes)  # CS over M0, M2 only
    trimmed = build_report(
        hand_rows(), BuildOptions(out_dir=tmp_path, trim=True, compare_paper=True, figures=False)
    )
    assert not any("not trimmed" in n or "not comparable" in n for n in trimmed.notes)


def test_all_zero_collisions_still_reports(tmp_path):
    rows = hand_rows().assign(CR_AA=0.0, CR_AL=0.0, CR_total=0.0)
    report = build_report(rows, BuildOptions(out_dir=tmp_path, figures=False))
    assert report.table.values.xs("CS", level="metric").isna().all().all()
    assert "composite score undefined: no model collided" in report.markdown


def test_missing_cell_is_a_dash_and_a_note(tmp_path):
    rows = hand_rows()
    rows = rows[~((rows.model == "M3") & (rows.scenario == "CPM"))]
    report = build_report(rows, BuildOptions(out_dir=tmp_path, figures=False))
    assert report.table.values.loc["CPM", "M3"].isna().all()
    assert "CPM: no evaluation rows for M3." in report.notes
    # CS over the other five (means CR 4.4/5, CD 12.5/5, AS 3.0/5): M2 = -0.4/0.88 - 2.5/2.5
    # + 0.55/0.6 = -0.5379.
    assert report.table.values.loc[("CPM", "CS"), "M2"] == pytest.approx(-0.5379, abs=1e-4)


def test_empty_input_is_a_clear_error(tmp_path):
    with pytest.raises(SigmarlError, match="no finished evaluation runs"):
        build_report(hand_rows().iloc[0:0], BuildOptions(out_dir=tmp_path))
    assert not any(tmp_path.iterdir())


def test_figures(tmp_path):
    curves = pd.DataFrame(
        [{"model": m, "seed": s, "iteration": i, "reward": i * 0.1 + s}
         for m in MODELS[:2] for s in (0, 1) for i in range(1, 6)]
    )  # fmt: skip
    rows = hand_rows(models=MODELS[:2])
    report = build_report(rows[rows.scenario.isin(SCENARIOS[:2])], BuildOptions(out_dir=tmp_path), curves)
    for key in ("distributions", "training_curves", "performance_profiles", "training_band", "heatmap"):
        assert report.paths[key].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_paper_numbers_only_beside_the_papers_maps(tmp_path):
    """A procedural map is not Table I's scenario: no paper numbers there, in any format."""
    rows = hand_rows()
    proc = rows[rows.scenario == "Roundabout"].assign(scenario="Proc-Roundabout")
    report = build_report(pd.concat([rows, proc]), BuildOptions(out_dir=tmp_path, compare_paper=True, latex=True,
                                                               figures=False))
    groups, current = {}, None
    for row in body(report.markdown):
        current = row[0] or current  # the group's name is on its first row only
        groups.setdefault(current, []).append(row)
    assert list(groups) == [*SCENARIOS, "Proc-Roundabout"]
    assert all("(" in cell for row in groups["Roundabout"] for cell in row[2:])
    assert not any("(" in cell for row in groups["Proc-Roundabout"] for cell in row[2:])
    assert "Proc-Roundabout: not in the paper's Table I, no paper numbers." in report.notes
    csv = pd.read_csv(report.paths["csv"])
    assert set(csv[csv.source == "paper"].scenario) == set(SCENARIOS)
    tex = report.paths["latex"].read_text()
    proc_block = tex.split("Proc-Roundabout}}")[1].split("\\bottomrule")[0]
    cells = [line.split(" & ")[1:] for line in proc_block.splitlines() if " & " in line]
    assert len(cells) == 6 and not any("(" in c for row in cells for c in row)


def test_one_column_is_a_table_without_comparisons_and_says_so(tmp_path):
    """One model: each metric over its mean across one model is 1, so the composite score
    (always -1) and the probabilities against itself say nothing; they are left out, once."""
    report = build_report(hand_rows(models=["M0"]), BuildOptions(out_dir=tmp_path, figures=False))
    assert report.table.values.xs("CS", level="metric").isna().all().all()
    assert report.table.values.loc[("CPM", "CD"), "M0"] == pytest.approx(CD[0])
    said = [n for n in report.notes if "nothing to compare" in n]
    assert said == ["All scenarios: one model: nothing to compare, so no composite score, "
                    "probability of improvement or verdict."]
    assert not (tmp_path / "statistics.md").exists() and not (tmp_path / "verdicts.md").exists()
    assert (tmp_path / "table.md").exists()
