"""The statistics wing stays study-free, and no module borrows another's private names."""

from __future__ import annotations

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src" / "sigmarl"


def _imports(path: Path) -> list[tuple[str, str]]:
    """(module, name) of every `from sigmarl... import name` in the file, at any depth."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    return [(node.module, alias.name) for node in ast.walk(tree)
            if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("sigmarl")
            for alias in node.names]


def test_no_module_imports_another_modules_private_name():
    borrowed = [f"{path.relative_to(SRC)}: {module}.{name}" for path in SRC.rglob("*.py")
                for module, name in _imports(path) if name.startswith("_") and not name.startswith("__")]
    assert not borrowed


def test_the_statistics_import_nothing_of_the_study():
    outside = [f"{path.name}: {module}" for path in (SRC / "stats").glob("*.py")
               for module, _ in _imports(path) if not module.startswith("sigmarl.stats")]
    assert not outside
