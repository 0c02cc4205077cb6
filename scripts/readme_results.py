"""Rewrite the README's results blocks from the committed study folders.

Each block between a pair of the README's markers (`<!-- results-table -->` ...
`<!-- /results-table -->`, and so on for BLOCKS) is the named file of
`sigmarl report --from results/paper-budget --compare-paper --ci` verbatim (likewise for the
generalisation study, and for the paper's rules, whose report reads results/paper-rules beside
results/paper-budget); tests/test_readme_results.py checks that they still are. Run after
committing new model-seeds:

    python scripts/readme_results.py
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from pathlib import Path

from sigmarl.cli import main as sigmarl

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
STUDY = "results/paper-budget"  # relative to ROOT: the report's notes name run folders by it
# README marker name -> the report file it holds
BLOCKS = {"results-table": "table.md", "results-statistics": "statistics.md", "results-training": "training.md",
          "results-verdicts": "verdicts.md", "results-curves": "curve_verdicts.md", "results-seeds": "seeds.md"}
# the generalisation study: the same models evaluated on the later maps and denser traffic
GENERALISATION = "results/generalisation"
GENERALISATION_BLOCKS = {"generalisation-matrix": "matrix.md", "generalisation-verdicts": "verdicts.md"}
# the paper's rules: its runs beside the study's runs under ours, which it reuses
RULES = "results/paper-rules"
RULES_BLOCKS = {"rules-verdicts": "verdicts.md"}


def report_files() -> dict[str, str]:
    """The reports' text for each block, by marker name."""
    return {**_report([STUDY], BLOCKS, ["--compare-paper"]),
            **_report([GENERALISATION], GENERALISATION_BLOCKS, ["study=generalisation"]),
            **_report([RULES, STUDY], RULES_BLOCKS, ["study=paper_rules"])}


def _report(folders: list[str], blocks: dict[str, str], options: list[str]) -> dict[str, str]:
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
        return {name: (Path(tmp) / file).read_text(encoding="utf-8") for name, file in blocks.items()}


def readme_block(text: str, name: str) -> tuple[int, int]:
    """Start and end offsets of the block between the markers `name`."""
    start_marker, end_marker = f"<!-- {name} -->\n", f"<!-- /{name} -->\n"
    if start_marker not in text:
        raise SystemExit(f"README.md has no {start_marker.strip()} marker")
    start = text.index(start_marker) + len(start_marker)
    return start, text.index(end_marker, start)


def warn_uncommitted() -> None:
    """The blocks name unfinished run folders; ones git does not hold yet make a README that a
    clean clone does not rebuild (tests/test_readme_results.py then fails there)."""
    try:
        out = subprocess.run(["git", "status", "--porcelain", "--", STUDY, GENERALISATION, RULES], cwd=ROOT,
                             capture_output=True, text=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        return
    if out.strip():
        print(f"warning: {STUDY}, {GENERALISATION} or {RULES} has {len(out.splitlines())} uncommitted change(s); "
              "commit them with the README, or a clean clone's README test fails", file=sys.stderr)


def main() -> None:
    warn_uncommitted()
    text = README.read_text(encoding="utf-8")
    for name, content in report_files().items():
        start, end = readme_block(text, name)
        text = text[:start] + content + text[end:]
    tmp = README.with_name(".README.md.tmp")  # a kill mid-write leaves the README whole
    tmp.write_text(text, encoding="utf-8")
    os.replace(tmp, README)


if __name__ == "__main__":
    main()
