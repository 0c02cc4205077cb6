"""The report's seam (`report.draft`): a section writes only the files it declares, no two
sections declare one file, and what a whole report writes is what the sections declare."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

from sigmarl.report.build import SECTIONS, build_report
from sigmarl.report.draft import BuildOptions, Draft, Section, UndeclaredFile, check_sections
from sigmarl.results.folders import read_imported, read_results

ROOT = Path(__file__).resolve().parents[1]


def _draft(tmp_path: Path, section: Section) -> Draft:
    draft = Draft(pd.DataFrame(), BuildOptions(out_dir=tmp_path), None, models=["M0"])
    draft.section = section
    return draft


def test_a_section_writes_what_it_declares_and_nothing_else(tmp_path):
    section = Section("mine", {"mine.md": "a page", "mine_<models>.json": "one per group"}, lambda d: None)
    draft = _draft(tmp_path, section)
    draft.write("page", "mine.md", "# Mine\n")
    draft.write("group", "mine_M0_M4.json", {"a": 1})
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mine.md", "mine_M0_M4.json"]
    assert draft.paths == {"page": tmp_path / "mine.md", "group": tmp_path / "mine_M0_M4.json"}
    for name in ("other.md", "mine.csv", "mine_.json", "mine_M0/x.json", "xmine.md"):
        with pytest.raises(UndeclaredFile, match=f"'mine' wrote '{name}'"):
            draft.write("x", name, "text")
    with pytest.raises(UndeclaredFile):  # a figure's path too
        draft.file("figure", "figure.png")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mine.md", "mine_M0_M4.json"]


def test_sections_are_named_once_and_each_file_has_one_section():
    check_sections(SECTIONS)
    one = Section("a", {"a.md": ""}, lambda d: None)
    with pytest.raises(ValueError, match="'a.md' declared by sections 'a' and 'b'"):
        check_sections([one, Section("b", {"a.md": ""}, lambda d: None)])
    with pytest.raises(ValueError, match=r"named twice: \['a'\]"):
        check_sections([one, Section("a", {"b.md": ""}, lambda d: None)])


def _spread(d: Draft) -> None:
    """A section of a user's own: each scenario's widest gap of CR_total between two columns."""
    cr = d.summary[d.summary["metric"] == "CR_total"]
    gap = cr.groupby("scenario", sort=False)["mean"].agg(lambda m: m.max() - m.min())
    d.write("spread", "spread.md", "".join(f"- {s}: {v:.3f} pp\n" for s, v in gap.items()))


SPREAD = Section("spread", {"spread.md": "per scenario, the widest gap of CR_total between columns"}, _spread)


def test_a_new_section_is_one_declaration_and_one_line_in_the_list(tmp_path):
    """Registered after the table (whose summary it reads), it writes its declared file, and the
    gaps it prints are those of the rows themselves (per model: the mean of its seed means)."""
    results = read_results(ROOT / "results" / "paper-budget")
    rows = results.rows[results.rows["model"].isin(["M0", "M4"]) & results.rows["seed"].isin([0, 1])]
    report = build_report(rows, BuildOptions(out_dir=tmp_path, figures=False), sections=[*SECTIONS[:2], SPREAD])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["composite_scores.csv", "matrix.md", "spread.md",
                                                       "summary.csv", "table.csv", "table.md"]
    seed_means = rows.groupby(["scenario", "model", "seed"])["CR_total"].mean().groupby(["scenario", "model"]).mean()
    gaps = (seed_means.groupby("scenario").max() - seed_means.groupby("scenario").min()) * 100
    lines = report.paths["spread"].read_text().splitlines()
    assert len(lines) == 4
    for line in lines:
        scenario, value = line[2:].split(": ")
        assert float(value.removesuffix(" pp")) == pytest.approx(gaps[scenario], abs=5e-4)


def test_every_file_a_whole_report_writes_is_declared_by_its_section(tmp_path):
    """The committed study, two models and three seeds each, every option on: each file on disk is
    one a section declares (so the reference page drawn from the declarations lists it), and every
    section but the conditional ones named here writes something."""
    results = read_results(ROOT / "results" / "paper-budget")
    keep = results.rows["model"].isin(["M0", "M4"]) & results.rows["seed"].isin([0, 1, 2])
    curves = results.curves[results.curves["model"].isin(["M0", "M4"]) & results.curves["seed"].isin([0, 1, 2])]
    imported = read_imported(ROOT / "results" / "paper-policies")  # the paper's own policies' section
    report = build_report(results.rows[keep], BuildOptions(out_dir=tmp_path, compare_paper=True, latex=True,
                                                           ci=True, imported=imported), curves)
    written = sorted(p.name for p in tmp_path.iterdir())
    owner = {name: next((s.name for s in SECTIONS if s.declares(name)), None) for name in written}
    assert None not in owner.values(), [n for n, s in owner.items() if s is None]
    assert sorted(p.name for p in report.paths.values()) == written
    silent = {s.name for s in SECTIONS} - set(owner.values())
    # study: it needs the columns' training configs, which only the command reads; benchmark: the
    # committed rows were written before its metrics were declared (not measured in them)
    assert silent == {"study", "benchmark"}


def test_the_reference_lists_every_declared_file_from_the_declarations():
    import importlib.util

    spec = importlib.util.spec_from_file_location("docs_reference", ROOT / "scripts" / "docs_reference.py")
    docs = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(docs)
    table = docs.report_files()
    for section in SECTIONS:
        assert f"### `{section.name}`" in table
        for name in section.files:
            assert f"| `{name}` |" in table
    page = (ROOT / "docs" / "reference" / "outputs.md").read_text(encoding="utf-8")
    assert page.count("<!-- generated: report-files -->") == 1  # drawn, not written by hand
    assert "`verdicts.md` (each" not in page  # the old hand-written list is gone
