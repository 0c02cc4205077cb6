"""Rewrite the README's results table from the committed study folder.

The block between the README's `<!-- results-table -->` markers is `table.md` of
`sigmarl report --from results/paper-budget --compare-paper --ci` verbatim;
tests/test_readme_results.py checks that it still is. Run after committing new model-seeds:

    python scripts/readme_results.py
"""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

from sigmarl.cli import main as sigmarl

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
STUDY = "results/paper-budget"  # relative to ROOT: the report's notes name run folders by it
START, END = "<!-- results-table -->\n", "<!-- /results-table -->\n"


def report_table() -> str:
    here = Path.cwd()
    with tempfile.TemporaryDirectory() as tmp:
        os.chdir(ROOT)  # tracking is off: the report writes only into `tmp`
        try:
            rc = sigmarl(["report", "--from", STUDY, "--out", tmp, "--compare-paper", "--ci", "--no-figures",
                          "tracking.enabled=false"])
        finally:
            os.chdir(here)
        if rc:
            sys.exit(rc)
        return (Path(tmp) / "table.md").read_text(encoding="utf-8")


def readme_table(text: str) -> tuple[int, int]:
    """Start and end offsets of the block between the markers."""
    start = text.index(START) + len(START)
    return start, text.index(END, start)


def main() -> None:
    text = README.read_text(encoding="utf-8")
    start, end = readme_table(text)
    tmp = README.with_name(".README.md.tmp")  # a kill mid-write leaves the README whole
    tmp.write_text(text[:start] + report_table() + text[end:], encoding="utf-8")
    os.replace(tmp, README)


if __name__ == "__main__":
    main()
