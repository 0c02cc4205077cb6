"""Comments and docstrings in src/, conf/ and tests/ state facts or link a docs page; none cites
a document the repository does not have (a spec's sections, a study file, an issue number);
a quoted file name (in quotes or backticks) is one the code writes (the report's "study.md")."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CITATION = re.compile(r'spec §|§\s*\d|(?<![\w/"`-])(?:study|environment|DESIGN)\.md\b|\bissue\s*#?\d+|\(#\d+\)|'
                      r"\bthe (?:reliability |statistics )?issue\b|\bissue's\b|\bthe spec\b", re.I)
THIS = Path(__file__).resolve()


def _files():
    for folder, pattern in (("src", "*.py"), ("conf", "*.yaml"), ("tests", "*.py")):
        for path in sorted((ROOT / folder).rglob(pattern)):
            if path.resolve() != THIS and "data" not in path.relative_to(ROOT).parts[1:2]:
                yield path


def test_no_line_cites_a_document_outside_the_repository():
    hits = [f"{path.relative_to(ROOT)}:{number}: {line.strip()}"
            for path in _files() for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1)
            if CITATION.search(line)]
    assert not hits, "say the fact, or link a docs page:\n" + "\n".join(hits)


def test_the_pattern_catches_what_it_must():
    for line in ("# spec §7.1", '"""Reward (spec §4)."""', "# study.md §5", "# see issue 12", "# fixed in (#21)",
                 "# the issue's own example"):
        assert CITATION.search(line), line
    for line in ("# the paper's Table I", "docs/results/paper-study.md", "spec = importlib.util.spec_from_file_location(...)", "# tissue",
                 'd.write("study", "study.md", text)', "the same header as `study.md`"):  # a file the code writes, quoted
        assert not CITATION.search(line), line
