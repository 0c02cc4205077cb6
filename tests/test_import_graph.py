"""The imports run one way: down the floors of `sigmarl.floors`, with no circle.

The graph is read from every import statement of every module, wherever it stands: at module
level, inside `if`/`try` blocks (so `if TYPE_CHECKING:` counts), and inside functions, methods
and classes (a lazy import is an arrow all the same, taken later). Circles are found as
strongly connected components (Tarjan). A package's `__init__` runs before any of its modules;
that arrow is not drawn, so a package whose rooms sit on different floors must open with no
sigmarl import at module level (checked below)."""

from __future__ import annotations

import ast
from pathlib import Path
from typing import NamedTuple

from sigmarl.floors import FLOORS, REPORT_FLOORS, UPWARD, floor_of

SRC = Path(__file__).resolve().parents[1] / "src"


class Arrow(NamedTuple):
    source: str  # the importing module
    target: str  # the imported one
    path: Path
    line: int
    lazy: bool  # inside a function


def _modules(root: Path) -> dict[str, Path]:
    out = {}
    for path in root.rglob("*.py"):
        parts = list(path.relative_to(root).with_suffix("").parts)
        out[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return out


def _statements(tree: ast.AST, lazy: bool = False):
    """(import statement, inside a function?) for every import anywhere in `tree`."""
    for node in ast.iter_child_nodes(tree):
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            yield node, lazy
        yield from _statements(node, lazy or isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)))


def _targets(node: ast.Import | ast.ImportFrom, name: str, path: Path, modules: dict[str, Path]) -> set[str]:
    if isinstance(node, ast.Import):  # `import a.b.c` runs a.b.c: the longest name that is a module
        out = set()
        for alias in node.names:
            target = alias.name
            while target and target not in modules:
                target = target.rpartition(".")[0]
            out |= {target} if target else set()
        return out
    base = node.module or ""
    if node.level:  # relative: from the module's package upwards
        package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
        base = ".".join(package[:len(package) - node.level + 1] + ([base] if base else []))
    # a submodule, else the module that holds the name
    return {f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base for a in node.names}


def arrows(root: Path) -> list[Arrow]:
    """Every import of a package module by another, one arrow per statement and target."""
    modules = _modules(root)
    out = []
    for name, path in sorted(modules.items()):
        for node, lazy in _statements(ast.parse(path.read_text(encoding="utf-8"))):
            out += [Arrow(name, t, path, node.lineno, lazy)
                    for t in sorted(_targets(node, name, path, modules)) if t in modules and t != name]
    return out


def import_graph(root: Path) -> dict[str, set[str]]:
    """Module -> the package modules it imports, anywhere in it."""
    graph: dict[str, set[str]] = {name: set() for name in _modules(root)}
    for a in arrows(root):
        graph[a.source].add(a.target)
    return graph


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            part = []
            while True:
                w = stack.pop()
                part.append(w)
                if w == v:
                    break
            if len(part) > 1:
                found.append(sorted(part))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def upward(found: list[Arrow], floor_of=floor_of, allowed=UPWARD, floors=FLOORS) -> list[str]:
    """Each arrow to a higher floor that `allowed` does not name, as `file:line: a -> b (...)`."""
    names = [f.name for f in floors]
    out = []
    for a in found:
        low, high = floor_of(a.source), floor_of(a.target)
        if low is not None and high is not None and high > low and (a.source, a.target) not in allowed:
            out.append(f"{a.path}:{a.line}: {a.source} ({names[low]}) imports {a.target} ({names[high]})"
                       + (" inside a function" if a.lazy else ""))
    return out


def _circle_lines(found: list[Arrow], circle: list[str]) -> list[str]:
    return [f"{a.path}:{a.line}: {a.source} -> {a.target}" for a in found if {a.source, a.target} <= set(circle)]


def test_sigmarl_imports_have_no_circle():
    graph = import_graph(SRC)
    assert len(graph) > 100 and graph["sigmarl.config"]  # the package is really read
    found = circles(graph)
    assert found == [], "\n".join(line for c in found for line in [f"circle of {len(c)}: {c}", *_circle_lines(arrows(SRC), c)])


def test_every_import_points_down_the_floors():
    bad = upward(arrows(SRC))
    assert bad == [], "imports up a floor (move what is borrowed, or name it in sigmarl.floors.UPWARD):\n" + "\n".join(bad)


def test_every_module_is_on_one_floor_and_every_room_exists():
    modules = _modules(SRC)
    assert [m for m in modules if floor_of(m) is None] == []
    rooms = [room for f in FLOORS for room in f.rooms]
    assert len(rooms) == len(set(rooms))
    assert [r for r in rooms if r not in modules] == []  # a stale room fails here
    used = {(a.source, a.target) for a in arrows(SRC)}
    assert len(UPWARD) <= 3 and all(pair in used and why for pair, why in UPWARD.items())


def _report_floor(module: str) -> int | None:
    inside = module == "sigmarl.report" or module.startswith("sigmarl.report.")
    return floor_of(module, REPORT_FLOORS) if inside else None


def test_the_reports_groups_import_down_their_own_floors():
    """Inside the report the same rule, over `REPORT_FLOORS`: a section module stands above what
    it draws, the seam above the groups, and no group reaches up into another (none allowed)."""
    modules = [m for m in _modules(SRC) if _report_floor(m) is not None]
    assert len(modules) > 12 and all(_report_floor(m) is not None for m in modules)
    rooms = [room for f in REPORT_FLOORS for room in f.rooms]
    assert [r for r in rooms if r not in _modules(SRC)] == []  # a stale room fails here
    assert {m for m in modules if _report_floor(m) == len(REPORT_FLOORS) - 1} == \
        {"sigmarl.report", "sigmarl.report.build"}  # the top: nothing else strays there
    bad = upward(arrows(SRC), floor_of=_report_floor, allowed={}, floors=REPORT_FLOORS)
    assert bad == [], "imports up the report's floors:\n" + "\n".join(bad)


def test_a_package_split_across_floors_opens_with_no_imports():
    modules = _modules(SRC)
    for name, path in modules.items():
        if path.name != "__init__.py" or name == "sigmarl":
            continue
        inside = {floor_of(m) for m in modules if m.startswith(name + ".")}
        if inside - {floor_of(name)}:
            top = [a for a in arrows(SRC) if a.source == name and not a.lazy]
            assert top == [], f"{name} holds rooms on several floors, so its __init__ may import nothing: {top}"


def _package(tmp_path: Path, files: dict[str, str]) -> Path:
    pkg = tmp_path / "p"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    for name, text in files.items():
        (pkg / name).write_text(text)
    return tmp_path


def test_the_measure_sees_type_only_and_lazy_imports(tmp_path):
    root = _package(tmp_path, {
        "a.py": "from p.b import f\n",
        "b.py": "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from p.a import g\n"
                "def f():\n    from p.c import h\n",
        "c.py": "from . import a\n",
        "d.py": "class K:\n    def m(self):\n        try:\n            import p.e.x\n        except ImportError:\n"
                "            pass\n",
        "e.py": "",
    })
    graph = import_graph(root)
    assert graph["p.b"] == {"p.a", "p.c"} and graph["p.c"] == {"p.a"}
    assert graph["p.d"] == {"p.e"}  # `import p.e.x` inside a method, inside a try: p.e is the module
    assert circles(graph) == [["p.a", "p.b", "p.c"]]
    lazy = [a for a in arrows(root) if a.lazy]
    assert [(a.source, a.target, a.line) for a in lazy] == [("p.b", "p.c", 5), ("p.d", "p.e", 4)]


def test_an_import_up_a_floor_is_named_with_its_line(tmp_path):
    root = _package(tmp_path, {"low.py": "import os\n\n\ndef f():\n    from p.high import g\n", "high.py": "import p.low\n"})
    floors = {"p.low": 0, "p.high": 1}
    bad = upward(arrows(root), floors.get, {})
    assert bad == [f"{root / 'p' / 'low.py'}:5: p.low (ground) imports p.high (config records) inside a function"]
    assert upward(arrows(root), floors.get, {("p.low", "p.high"): "a reason"}) == []


def test_the_architecture_page_draws_its_floor_table_from_the_floors():
    import importlib.util

    spec = importlib.util.spec_from_file_location("docs_reference", SRC.parent / "scripts" / "docs_reference.py")
    docs = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(docs)
    page = (SRC.parent / "docs" / "architecture.md").read_text(encoding="utf-8")
    assert page.count("<!-- generated: floors -->") == 1  # the table is not written by hand
    rows = [line for line in docs.expand(page).splitlines() if line.startswith("| ") and line.split(" | ")[0][2:3].isdigit()]
    assert [r.split(" | ")[0] for r in rows] == [f"| {i} {f.name}" for i, f in reversed(list(enumerate(FLOORS)))]
    assert "`tracking/`" in rows[-4] and "`params.py`" in rows[-1] and "`config/`" in rows[-2]  # packages as folders, modules as files
    assert "Imports up a floor: " + ("none." if not UPWARD else f"{len(UPWARD)},") in docs.expand(page)


def test_the_sweeps_own_process_does_not_import_torch():
    # the launcher gets sigmarl.sweep.task.run_job, which imports the job (torch, torchrl, the
    # environment: 4.5 s) only inside the job's process
    import subprocess
    import sys

    code = "import sys, sigmarl.sweep.launch, sigmarl.sweep.task; print('torch' in sys.modules)"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "False"
