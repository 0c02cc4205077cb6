"""The imports run one way: no circle among sigmarl's modules, type-only ones included.

The graph is read from the code (each module's imports at module level, inside `if` and `try`
blocks too, so `if TYPE_CHECKING:` counts; imports inside functions are lazy and do not), and
its circles found as strongly connected components (Tarjan)."""

from __future__ import annotations

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src"


def _modules(root: Path) -> dict[str, Path]:
    out = {}
    for path in root.rglob("*.py"):
        parts = list(path.relative_to(root).with_suffix("").parts)
        out[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return out


def _imports(node: ast.AST):
    if isinstance(node, (ast.Import, ast.ImportFrom)):
        yield node
    elif isinstance(node, (ast.If, ast.Try)):
        for body in (node.body, node.orelse, *(h.body for h in getattr(node, "handlers", ())),
                     getattr(node, "finalbody", ())):
            for child in body:
                yield from _imports(child)


def import_graph(root: Path) -> dict[str, set[str]]:
    """Module -> the package modules it imports at module level."""
    modules = _modules(root)
    graph = {}
    for name, path in modules.items():
        edges = set()
        for top in ast.parse(path.read_text()).body:
            for node in _imports(top):
                if isinstance(node, ast.Import):
                    edges |= {a.name for a in node.names if a.name in modules}
                    continue
                base = node.module or ""
                if node.level:  # relative: from the module's package upwards
                    package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
                    base = ".".join(package[:len(package) - node.level + 1] + ([base] if base else []))
                for alias in node.names:  # a submodule, else the package that holds the name
                    target = f"{base}.{alias.name}"
                    edges.add(target if target in modules else base)
        graph[name] = {e for e in edges if e in modules and e != name}
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


def test_sigmarl_imports_run_one_way():
    graph = import_graph(SRC)
    assert len(graph) > 100 and graph["sigmarl.config"]  # the package is really read
    assert circles(graph) == []


def test_the_measure_sees_a_type_only_circle(tmp_path):
    pkg = tmp_path / "p"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text("from p.b import f\n")
    (pkg / "b.py").write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from p.a import g\n"
                              "def f():\n    from p.c import h\n")
    (pkg / "c.py").write_text("from . import a\n")
    graph = import_graph(tmp_path)
    assert graph["p.b"] == {"p.a"} and graph["p.c"] == {"p.a"}  # the lazy import of p.c is not an edge
    assert circles(graph) == [["p.a", "p.b"]]


def test_the_sweeps_own_process_does_not_import_torch():
    # the launcher gets sigmarl.sweep.task.run_job, which imports the job (torch, torchrl, the
    # environment: 4.5 s) only inside the job's process
    import subprocess
    import sys

    code = "import sys, sigmarl.sweep.launch, sigmarl.sweep.task; print('torch' in sys.modules)"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "False"
