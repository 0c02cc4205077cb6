"""No figure of the results' prose is typed by hand where a generated block can hold it.

The README's "What the study found" states only figures of the paper report's `findings.md`
(held as the `results-findings` block of the paper's-study page, which tests/test_results_blocks.py
rebuilds byte for byte). On the paper's-study pages every decimal figure of the prose is one of
their generated blocks, at its printed precision, or a measurement the report does not make,
named below with where it comes from. So a new seed that moves a figure fails here until the
prose says the new one.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
NUMBER = re.compile(r"(?<![\w.])[-−+]?\d+(?:\.\d+)?(?![\w])")
# decimal figures of a page's prose that no block of it holds: each a measurement outside the
# report (wall clock, a simulation test, a test on another metric), with its source
OUTSIDE = {
    "docs/results/paper-study.md": {},
    "docs/results/paper-study-details.md": {
        "16.4": "training compute of the first 18 model-seeds (their metrics.csv, summed by hand once)",
        "8.2": "wall clock of the first 18 model-seeds with two jobs at a time",
        "9.5": "seconds per training iteration with a core to itself (benchmarks/bench_training.py)",
        "1.96": "marl-eval's own z",
        # CD is not a verdict metric of the study: `study.metrics=[CR_total,CD]` tests it
        "0.007": "Holm-adjusted permutation p of CD on CPM (M5 against M0)",
        "0.394": "Holm-adjusted permutation p of CD on the Intersection (M5 against M0)",
        "0.154": "Holm-adjusted permutation p of CD on the Roundabout (M5 against M0)",
        "0.189": "permutation p of CD on the On-Ramp (M5 against M0)",
        "0.006": "permutation p of CD on the Roundabout (M5 against M0)",
        "0.016": "permutation p of CD on the Intersection (M5 against M0)",
        "0.288": "M5 - M0 in CD on CPM (that report's verdicts.md)",
        "0.153": "M5 - M0 in CD on the Intersection",
        "0.119": "M5 - M0 in CD on the On-Ramp",
        "0.158": "M5 - M0 in CD on the Roundabout",
    },
}
# the paper's study is two pages, the page and its appendix: the prose of either may state a
# figure of either's blocks
STUDY_PAGES = ("docs/results/paper-study.md", "docs/results/paper-study-details.md")


def _parts(text: str) -> tuple[str, str]:
    """(the generated blocks, the prose) of a page; code blocks and spans belong to neither."""
    blocks, prose, inside, code = [], [], None, False
    for line in text.splitlines():
        marker = re.match(r"<!-- (/?)([\w-]+) -->$", line)
        if marker:
            inside = None if marker.group(1) else marker.group(2)
        elif line.startswith("```"):
            code = not code
        elif inside:
            blocks.append(line)
        elif not code:
            prose.append(line)
    return "\n".join(blocks), "\n".join(prose)


def _numbers(text: str) -> list[str]:
    text = re.sub(r"`[^`]*`", " ", text)  # commands and paths
    text = re.sub(r"\]\([^)]*\)", "]", text)  # link targets
    text = re.sub(r"\b(M\d+|seed\d+|Fig\. \d+|Table I+)\b", " ", text)  # names, not figures
    return [n.replace("−", "-").lstrip("+-") for n in NUMBER.findall(text)]


def _held(figure: str, pool: list[float], exact: bool = False) -> bool:
    digits = len(figure.split(".")[1]) if "." in figure else 0
    value = float(figure)
    if exact:
        return any(f"{p:.{digits}f}" == figure for p in pool)
    return any(abs(round(abs(p), digits) - value) < 1e-9 for p in pool)


def _page(name: str) -> str:
    return (ROOT / name).read_text(encoding="utf-8")


def _findings() -> str:
    page = _page("docs/results/paper-study.md")
    start = page.index("<!-- results-findings -->\n")
    return page[start:page.index("<!-- /results-findings -->", start)]


def test_the_readme_states_only_the_findings_figures() -> None:
    readme = _page("README.md")
    section = readme[readme.index("## What the study found"):]
    section = section[:section.index("<!-- results-table -->")]
    pool = [float(n) for n in _numbers(_findings())]
    figures = _numbers(section)
    assert len(figures) >= 5, "the README's findings paragraph lost its figures"
    stray = [f for f in figures if not _held(f, pool, exact=True)]
    assert not stray, f"README's findings state figures that findings.md does not: {stray}"


@pytest.mark.parametrize("page", STUDY_PAGES)
def test_decimal_figures_of_a_results_page_come_from_its_blocks(page) -> None:
    _, prose = _parts(_page(page))
    pool = [float(n) for other in STUDY_PAGES for n in _numbers(_parts(_page(other))[0])]
    outside = OUTSIDE.get(page, {})
    decimals = [f for f in _numbers(prose) if "." in f]
    stray = sorted({f for f in decimals if f not in outside and not _held(f, pool)})
    assert not stray, f"{page}'s prose states figures no generated block holds: {stray}"
    unused = sorted(set(outside) - set(decimals))
    assert not unused, f"OUTSIDE names figures {page} no longer states: {unused}"


def test_the_check_catches_a_drifted_figure() -> None:
    """A drifted figure: a probability the prose gave one way, the block another."""
    blocks, _ = _parts(_page("docs/results/paper-study.md"))
    pool = [float(n) for n in _numbers(blocks)]
    assert _held("0.57", pool) and not _held("0.5432", pool)


def test_the_paper_study_page_reads_as_a_manual() -> None:
    """The page is its findings, in at most 5,000 words (as `wc -w` counts them, tables included),
    of which at most 1,500 are prose outside the tables and the generated blocks; the details
    move to its appendix and the history to the changelog."""
    text = _page("docs/results/paper-study.md")
    _, prose = _parts(text)
    prose_words = sum(len(line.split()) for line in prose.splitlines() if not line.startswith("|"))
    assert len(text.split()) <= 5000 and prose_words <= 1500, (len(text.split()), prose_words)


@pytest.mark.parametrize("page", sorted(p.relative_to(ROOT).as_posix() for p in (ROOT / "docs" / "results").glob("*.md")))
def test_a_results_page_opens_with_its_conclusion(page) -> None:
    """Under the title, a paragraph of prose comes first: not a section, table, figure or command."""
    lines = _page(page).splitlines()
    assert lines[0].startswith("# "), page
    first = next(line for line in lines[1:] if line.strip())
    assert not first.startswith(("#", "|", "!", "```", "<!--", "-")), (page, first)
    paragraph = lines[lines.index(first):]
    paragraph = paragraph[:paragraph.index("") if "" in paragraph else len(paragraph)]
    assert len(" ".join(paragraph).split()) >= 40, (page, "the opening paragraph is too short to conclude anything")
