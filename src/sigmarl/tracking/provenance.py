"""What a training ran on: the versions of Python and of the libraries its numbers depend on, the
CPU and GPU models, the thread count, and the sigmarl commit with whether its tree was dirty.

Each start of a training (the first and every resume) adds one record to the run folder's
`provenance.json` and sets the same values as `provenance.*` tags of its MLflow run. The report's
study page lists them per column (`report/study.py`); a run folder from before this
has no file, and reads as "not recorded".
"""

from __future__ import annotations

import json
import platform
import subprocess
from importlib import metadata
from pathlib import Path
from typing import Any

from sigmarl.errors import SigmarlError
from sigmarl.run import Run, write_atomic
from sigmarl.tracking.meta import git_commit

FORMAT = 1
PACKAGES = ("torch", "torchrl", "tensordict", "vmas", "hydra-core", "mlflow", "numpy")
# the record's keys in the order the study page shows them
KEYS = ("python", *PACKAGES, "cpu", "gpu", "device", "threads", "sigmarl_commit", "dirty")


def _version(package: str) -> str:
    try:
        return metadata.version(package)
    except metadata.PackageNotFoundError:
        return "not installed"


def cpu_model() -> str:
    """The CPU's model name (/proc/cpuinfo on Linux, else what the platform says)."""
    try:
        for line in Path("/proc/cpuinfo").read_text(encoding="utf-8", errors="replace").splitlines():
            if line.lower().startswith(("model name", "hardware")):
                return " ".join(line.split(":", 1)[1].split())
    except OSError:
        pass
    return platform.processor() or platform.machine() or "unknown"


def gpu_model() -> str:
    """The first CUDA device's name, or "none" (torch is imported by then: the training has it)."""
    import torch  # lazy: only a training records this, and it has torch loaded

    return torch.cuda.get_device_name(0) if torch.cuda.is_available() else "none"


def tree_dirty(start: Path | None = None) -> bool | None:
    """Whether tracked files of sigmarl's checkout differ from its commit; None outside a
    checkout or without git (the commit itself is read without git, `meta.git_commit`)."""
    folder = (start or Path(__file__)).resolve().parent
    try:
        done = subprocess.run(["git", "-C", str(folder), "status", "--porcelain", "--untracked-files=no"],
                              capture_output=True, text=True, timeout=20)
    except (OSError, subprocess.SubprocessError):
        return None
    return bool(done.stdout.strip()) if done.returncode == 0 else None


def collect(threads: int, device: str) -> dict[str, Any]:
    """This process's record (see the module's docstring)."""
    return {"python": platform.python_version(), **{p: _version(p) for p in PACKAGES}, "cpu": cpu_model(),
            "gpu": gpu_model(), "device": str(device), "threads": int(threads), "sigmarl_commit": git_commit(),
            "dirty": tree_dirty()}


def as_tags(record: dict[str, Any]) -> dict[str, str]:
    """The record as MLflow tags (`provenance.torch`, ...)."""
    return {f"provenance.{k}": str(record.get(k)) for k in KEYS}


def read(run: Run) -> list[dict[str, Any]] | None:
    """The run folder's records, first start first; None where it has none (a run from before
    sigmarl recorded them)."""
    path = run.provenance_file
    if not path.is_file():
        return None
    try:
        records = json.loads(path.read_text(encoding="utf-8"))["records"]
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise SigmarlError(f"{path} is not a provenance record ({type(e).__name__}); delete it to read the run "
                           "as not recorded") from e
    return [r for r in records if isinstance(r, dict)] or None


def add(run: Run, record: dict[str, Any], from_iteration: int) -> None:
    """Append `record` (a start at `from_iteration`) to the folder's records; a resumed run from
    before sigmarl recorded them starts its list here."""
    try:
        records = read(run) or []
    except SigmarlError:  # damaged: what it said is lost either way; keep the runs' record going
        records = []
    records.append({"from_iteration": int(from_iteration), **record})
    write_atomic(run.provenance_file, json.dumps({"format": FORMAT, "records": records}, indent=1) + "\n")
