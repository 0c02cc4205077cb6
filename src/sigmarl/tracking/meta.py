"""What a run is tagged with: flat params and the git commit."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from sigmarl.config import flatten as flat_dict


def flatten(d: Mapping[str, Any], prefix: str = "") -> dict[str, str]:
    """{"ppo": {"lr": 2e-4}} -> {"ppo.lr": "0.0002"} (params are text); lists stay one value."""
    return {k: str(v) for k, v in flat_dict(d, prefix).items()}


def git_commit(start: Path | None = None) -> str | None:
    """The checkout's commit, read from .git files (no git process); None outside a checkout."""
    here = (start or Path(__file__)).resolve()
    for folder in [here, *here.parents]:
        git = folder / ".git"
        if git.is_file():  # worktree or submodule: "gitdir: <path>"
            text = git.read_text().strip()
            if not text.startswith("gitdir:"):
                return None
            git = (folder / text.removeprefix("gitdir:").strip()).resolve()
        if not git.is_dir():
            continue
        try:
            head = (git / "HEAD").read_text().strip()
            if not head.startswith("ref:"):
                return head or None
            ref = head.removeprefix("ref:").strip()
            common = git / "commondir"
            roots = [git] + ([(git / common.read_text().strip()).resolve()] if common.is_file() else [])
            for root in roots:
                if (root / ref).is_file():
                    return (root / ref).read_text().strip()
                packed = root / "packed-refs"
                if packed.is_file():
                    for line in packed.read_text().splitlines():
                        if line.endswith(f" {ref}"):
                            return line.split()[0]
        except OSError:
            return None
        return None
    return None
