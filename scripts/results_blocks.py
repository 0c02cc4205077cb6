"""Rewrite the generated results blocks of the README and the docs' results pages from the
committed study folders.

A block is the text between a pair of markers (`<!-- results-table -->` ...
`<!-- /results-table -->`) in a page; it holds one file of a report verbatim. REPORTS says how
each report is made (`sigmarl report --from FOLDER ... --ci`), BLOCKS which file of which
report each marker holds and the pages that carry it (a block may stand in several).
tests/test_results_blocks.py checks that every block still is its report's file. Run after
committing new model-seeds:

    python scripts/results_blocks.py

To add a block: a marker pair in a page, and one BLOCKS entry (and a REPORTS entry for a new
report).
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from pathlib import Path

from sigmarl.cli import main as sigmarl
from sigmarl.report.sections import TABLE_HEADING

ROOT = Path(__file__).resolve().parents[1]
STUDY = "results/paper-budget"  # relative to ROOT: the report's notes name run folders by it
# the generalisation study: the same models evaluated on the later maps and denser traffic
GENERALISATION = "results/generalisation"
# the paper's rules: its runs beside the study's runs under ours, which it reuses
RULES = "results/paper-rules"
# the rule-based driver: its one evaluation beside the study's M0
RULE_BASED = "results/rule-based"
# report name -> (its folders, its options)
REPORTS = {"paper": ([STUDY], ["--compare-paper"]),
           "generalisation": ([GENERALISATION], ["study=generalisation"]),
           "rules": ([RULES, STUDY], ["study=paper_rules"]),
           "rule_based": ([RULE_BASED, STUDY], ["study=rule_based", "+study.variants.M0=['obs=full']"])}
PAPER_PAGE, RULES_PAGE, GENERALISATION_PAGE = ("docs/results/paper-study.md", "docs/results/paper-rules.md",
                                                "docs/results/generalisation.md")
# the paper's study's appendix: the statistics, verdicts, seeds and training behind its page
DETAILS_PAGE = "docs/results/paper-study-details.md"
# marker name -> (report, the report's file, the pages that hold the block)
BLOCKS = {
    "results-replication": ("paper", "replication.md", (PAPER_PAGE,)),
    "results-paper-policies": ("paper", "paper_policies.md", (PAPER_PAGE,)),
    "results-table": ("paper", "table.md", ("README.md", PAPER_PAGE)),
    "results-findings": ("paper", "findings.md", (PAPER_PAGE,)),
    "results-statistics": ("paper", "statistics.md", (DETAILS_PAGE,)),
    "results-verdicts": ("paper", "verdicts.md", (DETAILS_PAGE,)),
    "results-seeds": ("paper", "seeds.md", (DETAILS_PAGE,)),
    "results-training": ("paper", "training.md", (DETAILS_PAGE,)),
    "results-curves": ("paper", "curve_verdicts.md", (DETAILS_PAGE,)),
    "rule-based-matrix": ("rule_based", "matrix.md", (PAPER_PAGE,)),
    "rules-verdicts": ("rules", "verdicts.md", (RULES_PAGE,)),
    "generalisation-matrix": ("generalisation", "matrix.md", (GENERALISATION_PAGE,)),
    "generalisation-verdicts": ("generalisation", "verdicts.md", (GENERALISATION_PAGE,)),
}


def report_files() -> dict[str, str]:
    """Each block's text, by marker name, from the reports it comes from (each made once)."""
    reports = {name: _report(*REPORTS[name]) for name in {report for report, _, _ in BLOCKS.values()}}
    return {marker: reports[report][file] for marker, (report, file, _) in BLOCKS.items()}


def _report(folders: list[str], options: list[str]) -> dict[str, str]:
    """The report's Markdown files by name."""
    here = Path.cwd()
    sources = [arg for folder in folders for arg in ("--from", folder)]
    with tempfile.TemporaryDirectory() as tmp:
        os.chdir(ROOT)  # tracking is off: the report writes only into `tmp`
        try:
            rc = sigmarl(["report", *sources, "--out", tmp, "--ci", "--no-figures", *options,
                          "tracking.enabled=false"])
        finally:
            os.chdir(here)
        if rc:
            sys.exit(rc)
        files = {p.name: p.read_text(encoding="utf-8") for p in Path(tmp).glob("*.md")}
    # a page's block holds the table itself; what its columns are is the page's own prose
    files["table.md"] = files["table.md"].split(f"\n{TABLE_HEADING}\n\n", 1)[-1]
    # and under the page's own heading, a file's title would be a second page title
    for name, text in files.items():
        if text.startswith("# "):
            files[name] = text.split("\n", 1)[-1].lstrip("\n")
    return files


def block(text: str, name: str, page: str = "README.md") -> tuple[int, int]:
    """Start and end offsets of the block between the markers `name`."""
    start_marker, end_marker = f"<!-- {name} -->\n", f"<!-- /{name} -->\n"
    if start_marker not in text:
        raise SystemExit(f"{page} has no {start_marker.strip()} marker")
    start = text.index(start_marker) + len(start_marker)
    return start, text.index(end_marker, start)


def blocks_of_page(page: str) -> list[str]:
    """The markers a page holds."""
    return [marker for marker, (_, _, pages) in BLOCKS.items() if page in pages]


def pages() -> list[str]:
    return sorted({page for _, _, held in BLOCKS.values() for page in held})


def warn_uncommitted() -> None:
    """The blocks name unfinished run folders; ones git does not hold yet make pages that a
    clean clone does not rebuild (tests/test_results_blocks.py then fails there)."""
    try:
        out = subprocess.run(["git", "status", "--porcelain", "--", STUDY, GENERALISATION, RULES, RULE_BASED], cwd=ROOT,
                             capture_output=True, text=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        return
    if out.strip():
        print(f"warning: {STUDY}, {GENERALISATION}, {RULES} or {RULE_BASED} has {len(out.splitlines())} uncommitted change(s); "
              "commit them with the pages, or a clean clone's results-blocks test fails", file=sys.stderr)


def main() -> None:
    warn_uncommitted()
    rebuilt = report_files()
    for page in pages():
        path = ROOT / page
        text = path.read_text(encoding="utf-8")
        for name in blocks_of_page(page):
            start, end = block(text, name, page)
            text = text[:start] + rebuilt[name] + text[end:]
        tmp = path.with_name(f".{path.name}.tmp")  # a kill mid-write leaves the page whole
        tmp.write_text(text, encoding="utf-8")
        os.replace(tmp, path)


if __name__ == "__main__":
    main()
