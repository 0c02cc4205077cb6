"""The manual reads as reference: no prose paragraph over 150 words (code, tables and generated
blocks aside; each list item its own paragraph), and every image under docs/ is shown on a page."""

from __future__ import annotations

import re
from pathlib import Path

DOCS = Path(__file__).resolve().parents[1] / "docs"
LIMIT = 150
ITEM = re.compile(r"\s*([-*+] |\d+\. )")
MARKER = re.compile(r"<!-- (/?)[\w-]+ -->\s*$")


def paragraphs(text: str) -> list[tuple[int, str]]:
    """(first line number, text) of each prose paragraph or list item of a Markdown page."""
    out: list[tuple[int, str]] = []
    current: list[str] = []
    start = 0
    fenced = generated = False

    def close() -> None:
        if current:
            text = " ".join(s.strip() for s in current)
            out.append((start, ITEM.sub("", text, count=1)))
            current.clear()

    for number, line in enumerate(text.splitlines(), 1):
        if line.lstrip().startswith(("```", "~~~")):
            fenced = not fenced
            close()
            continue
        if marker := MARKER.match(line.strip()):
            generated = not marker.group(1)
            close()
            continue
        skip = fenced or generated or line.lstrip().startswith(("|", "#", "<", "!["))
        if skip or not line.strip():
            close()
            continue
        if ITEM.match(line):
            close()
        if not current:
            start = number
        current.append(line)
    close()
    return out


def words(text: str) -> int:
    return len(text.split())


def test_the_counter_on_a_hand_made_page() -> None:
    page = "\n".join([
        "# Title", "", "one two", "three", "", "- item a b", "  c d", "- item e", "",
        "```", "x " * 200, "```", "", "<!-- results-table -->", "y " * 200, "<!-- /results-table -->",
        "", "| a | b |", "", "last words here"])
    assert [(n, words(t)) for n, t in paragraphs(page)] == [(3, 3), (6, 5), (8, 2), (20, 3)]


def test_no_prose_paragraph_is_over_the_limit() -> None:
    long = [f"{page.relative_to(DOCS)}:{line} ({words(text)} words)"
            for page in sorted(DOCS.rglob("*.md"))
            for line, text in paragraphs(page.read_text(encoding="utf-8"))
            if words(text) > LIMIT]
    assert not long, "paragraphs over 150 words: " + ", ".join(long)


def test_every_image_is_shown_on_a_page() -> None:
    pages = {page: page.read_text(encoding="utf-8") for page in DOCS.rglob("*.md")}
    shown = set()
    for page, text in pages.items():
        for target in re.findall(r"!\[[^\]]*\]\(([^)\s]+)", text) + re.findall(r'<img[^>]+src="([^"]+)"', text):
            shown.add((page.parent / target).resolve())
    images = [p for ext in ("png", "gif", "svg", "jpg") for p in DOCS.rglob(f"*.{ext}")]
    assert images, "the manual lost its figures"
    unshown = sorted(str(p.relative_to(DOCS)) for p in images if p.resolve() not in shown)
    assert not unshown, f"images no page shows: {unshown}"
