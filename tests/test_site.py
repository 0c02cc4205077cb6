"""The documentation site: `mkdocs build --strict` passes, a broken link fails it, and the built
site, served on 127.0.0.1 and loaded in headless Chromium, renders its images and tables (Table I
fits its column; a wider table scrolls sideways, none is clipped) and has a search index. Skips where mkdocs or Chromium is missing."""

from __future__ import annotations

import functools
import html
import http.server
import json
import os
import re
import shutil
import subprocess
import sys
import threading
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
pytestmark = pytest.mark.slow


def _mkdocs(config: Path, site: Path) -> subprocess.CompletedProcess:
    pytest.importorskip("mkdocs")
    pytest.importorskip("material")
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}
    return subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-f", str(config), "-d", str(site)],
                          cwd=ROOT, capture_output=True, text=True, timeout=600, env=env)


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    site = tmp_path_factory.mktemp("site")
    done = _mkdocs(ROOT / "mkdocs.yml", site)
    assert done.returncode == 0, done.stderr[-3000:]
    return site


def test_the_site_builds_with_every_page(site):
    for page in ("index.html", "getting-started/index.html", "reference/config/index.html",
                 "reference/cli/index.html", "results/paper-study/index.html", "tutorials/own-ablation/index.html"):
        assert (site / page).exists(), page
    config = (site / "reference" / "config" / "index.html").read_text(encoding="utf-8")
    assert "<code>ppo.lr</code>" in config and "Learning rate at the first iteration" in config  # generated
    assert "generated:" not in config  # every marker replaced
    for path in [*(ROOT / "conf" / "study").glob("*.yaml"), *(ROOT / "conf" / "scenario").glob("*.yaml")]:
        option = f"study={path.stem}" if path.parent.name == "study" else path.stem
        assert f"<code>{option}</code>" in config, f"{path.name} is not on the configuration page"
    cli = (site / "reference" / "cli" / "index.html").read_text(encoding="utf-8")
    assert "sigmarl sweep" in cli and "--compare-paper" in cli
    architecture = (site / "architecture" / "index.html").read_text(encoding="utf-8")
    assert "generated:" not in architecture and "<code>floors.py</code>" in architecture  # the floor table


def test_a_broken_link_fails_the_strict_build(tmp_path):
    docs = tmp_path / "docs"
    shutil.copytree(ROOT / "docs", docs)
    with (docs / "concepts.md").open("a", encoding="utf-8") as f:
        f.write("\nSee [a page that is not there](no-such-page.md).\n")
    config = tmp_path / "mkdocs.yml"
    config.write_text(f"INHERIT: {ROOT / 'mkdocs.yml'}\ndocs_dir: {docs}\nhooks:\n  - {ROOT / 'scripts' / 'docs_reference.py'}\n")
    done = _mkdocs(config, tmp_path / "site")
    assert done.returncode != 0
    assert "no-such-page.md" in done.stderr and "concepts.md" in done.stderr


def _chromium() -> str:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        if path := shutil.which(name):
            return path
    pytest.skip("no Chromium (apt-get install chromium)")


class _Log(http.server.SimpleHTTPRequestHandler):
    served: list[tuple[str, int]] = []

    def log_request(self, code="-", size="-"):
        self.served.append((self.path, int(code)))


@pytest.fixture(scope="module")
def served(site):
    _Log.served = []
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), functools.partial(_Log, directory=str(site)))
    threading.Thread(target=server.serve_forever, daemon=True).start()
    yield f"http://127.0.0.1:{server.server_address[1]}", _Log.served
    server.shutdown()


def _browse(url: str, *options: str) -> str:
    chromium = _chromium()
    done = subprocess.run([chromium, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
                           "--virtual-time-budget=5000", *options, url],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout


@pytest.mark.parametrize("page, image, height", [("", "maps/scenarios.png", 1400),
                                                 ("results/paper-study/", "results/distributions.png", 4200)])
def test_pages_render_their_images_and_tables_in_chromium(served, tmp_path, page, image, height):
    base, log = served
    dom = _browse(f"{base}/{page}", "--dump-dom")
    assert "<table" in dom and "<img" in dom and image.split("/")[-1] in dom
    assert any(path.endswith(image) and code == 200 for path, code in log), log  # the browser fetched it
    assert not [(path, code) for path, code in log if code >= 400], log
    shots = Path(os.environ.get("SIGMARL_SITE_SHOTS", tmp_path))
    shots.mkdir(parents=True, exist_ok=True)
    shot = shots / f"{page.strip('/').replace('/', '_') or 'home'}.png"
    _browse(f"{base}/{page}", f"--screenshot={shot}", f"--window-size=1280,{height}")
    assert shot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and shot.stat().st_size > 20_000


def test_the_search_index_exists_and_covers_the_pages(site, served):
    index = json.loads((site / "search" / "search_index.json").read_text(encoding="utf-8"))
    locations = {doc["location"].split("#")[0] for doc in index["docs"]}
    assert {"", "concepts/", "reference/config/", "results/paper-study/"} <= locations
    assert any("seeds=auto" in doc["text"] for doc in index["docs"])


# Appended to a page: after Material has wrapped each table in its scrolling container, the
# widths the browser laid out, written into the DOM for --dump-dom to return.
_MEASURE = """<script>addEventListener("load", () => setTimeout(() => {
  const column = document.querySelector("article").getBoundingClientRect();
  const out = [...document.querySelectorAll("article table")].map(t => {
    const box = t.closest(".md-typeset__scrollwrap") || t.parentElement;
    return {head: [...t.rows[0].cells].map(c => c.innerText.trim()), width: t.getBoundingClientRect().width,
            right: t.getBoundingClientRect().right, column: column.right, box: box.clientWidth,
            scroll: box.scrollWidth, overflow: getComputedStyle(box).overflowX};
  });
  const pre = document.createElement("pre"); pre.id = "measured"; pre.textContent = JSON.stringify(out);
  document.body.append(pre);
}, 100));</script>"""


def _tables(site: Path, base: str, page: str, width: int = 1280) -> list[dict]:
    """The laid-out widths of each table of a page in a window `width` px wide."""
    measured = site / page / "measure.html"
    measured.write_text((site / page / "index.html").read_text(encoding="utf-8").replace("</body>", _MEASURE + "</body>"),
                        encoding="utf-8")
    dom = _browse(f"{base}/{page}/measure.html", f"--window-size={width},1200", "--dump-dom")
    found = re.search(r'<pre id="measured">(.*?)</pre>', dom, re.S)
    assert found, dom[-2000:]
    return json.loads(html.unescape(found.group(1)))


def test_table_one_fits_its_column_and_no_table_is_clipped(site, served):
    """Every table of the paper's-study page fits the content column of a 1280 px window (Table I's
    eight columns: M5 not cut off on the right; the replication table's ten), and every table of
    the other pages of wide tables either fits or scrolls sideways in its box."""
    base, _ = served
    for page in ("results/paper-study", "results/paper-study-details", "results/paper-rules",
                 "results/generalisation", "performance"):
        tables = _tables(site, base, page)
        assert tables, page
        for t in tables:
            fits = t["scroll"] <= t["box"] + 1 and t["right"] <= t["column"] + 1
            scrolls = t["overflow"] in ("auto", "scroll") and t["scroll"] >= t["width"] - 1
            assert fits or scrolls, (page, t)
        if page == "results/paper-study":
            assert any(t["head"] == ["Scenario", "Metric", "M0", "M1", "M2", "M3", "M4", "M5"] for t in tables)
            for t in tables:
                assert t["scroll"] <= t["box"] + 1 and t["right"] <= t["column"] + 1, t
