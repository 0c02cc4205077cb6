"""A run folder, `<runs_root>/<label>/seed<k>/`: the record of one training run and its
evaluation. The folder, not an in-memory object, owns a run; this module is the one place that
knows its files, its states, how a file in it is written, and who may write it.

- Every file is written whole or not at all: `write_atomic` writes a temporary file beside the
  target, flushes it to disk, and renames it over the target (a kill leaves the old file or
  the new one, never half of one).
- One live process writes a run folder at a time: `Run.lock()` takes an `flock` on
  `.seed<k>.lock` beside the folder (outside it, so that taking it creates nothing inside),
  named from the resolved folder (a symlink or a `..` spelling of it takes the same lock),
  which the kernel releases when its holder dies, however it dies (a kill -9 included), so a
  lock never outlives its process and a re-run needs no clean-up.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import socket
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import BinaryIO

from sigmarl.errors import SigmarlError

# The files of a run folder.
CONFIG_FILE = "config.yaml"  # the resolved training config, with its label and fingerprint
METRICS_FILE = "metrics.csv"  # one row per training iteration
RESUME_FILE = "checkpoint.pt"  # the resume point: weights, optimiser, generators
BEST_FILE = "best.pt"  # the policy with the best mean episode reward (to 2 decimals)
FINAL_FILE = "final.pt"  # the policy after the last iteration
RUN_ID_FILE = "mlflow_run_id"  # the training's MLflow run
ROWS_FILE = "evaluation_rows.csv"  # one row per (scenario, simulation)
ROWS_META = "evaluation.json"  # what measured the rows (protocol key, checkpoint hash, rules)
DONE_FILE = "evaluated.txt"  # the sweep's mark: trained and evaluated (the evaluation run id)
FAILED_FILE = "failed.txt"  # the sweep's mark: the job failed (the error)
BLOCK_FILE = "block.json"  # a seed block's seed: the block it trains in (its seeds)
NEXT_RESUME_FILE = "checkpoint.next.pt"  # a block's resume point while its seeds' are committed together
PROVENANCE_FILE = "provenance.json"  # what each start of the training ran on (tracking/provenance.py)

# The metric whose history tells which iterations a training run holds (metrics.csv, MLflow).
REWARD_COLUMN = "episode_reward_mean"
# The paper's definition of it, estimated from the same batch (`training.mappo.complete_episode_reward`);
# runs trained before it lack the column.
COMPLETE_REWARD_COLUMN = "episode_reward_mean_complete"


def write_atomic(path: Path, data: str | bytes | Callable[[BinaryIO], None]) -> None:
    """Write `data` (text, bytes, or a function that writes into the open binary file) to
    `path` whole or not at all (see the module's docstring)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            if callable(data):
                data(f)
            else:
                f.write(data.encode("utf-8") if isinstance(data, str) else data)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, 0o644)  # mkstemp makes it owner-only
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    _fsync_dir(path.parent)


def _fsync_dir(folder: Path) -> None:
    """Make the rename itself durable (a power cut after it keeps the new file)."""
    with contextlib.suppress(OSError):  # a folder that cannot be opened or synced: nothing to do
        fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def checkpoint_name(which: str) -> str:
    """The file of eval.checkpoint (`best` or `final`) in a run folder."""
    if which not in ("best", "final"):
        raise SigmarlError(f"eval.checkpoint must be 'best' or 'final', got {which!r}")
    return BEST_FILE if which == "best" else FINAL_FILE


# Locks this process holds: path -> [fd, depth] (flock is per open file, so a second open in
# the same process would block on its own lock; nested holders share the first).
_HELD: dict[str, list[int]] = {}


class Run:
    """A run folder: its files' paths, its state, its lock."""

    def __init__(self, folder: str | Path) -> None:
        self.dir = Path(folder)

    def __repr__(self) -> str:
        return f"Run({str(self.dir)!r})"

    @property
    def lock_file(self) -> Path:
        # keyed on the folder itself, not its spelling: a symlink, `..` or a relative path to
        # one folder is one writer
        folder = self.dir.resolve()
        return folder.parent / f".{folder.name}.lock"

    def path(self, name: str) -> Path:
        return self.dir / name

    # Each file of the folder, by what it holds (the only place that joins folder and name).
    config_file = property(lambda self: self.path(CONFIG_FILE))
    metrics_file = property(lambda self: self.path(METRICS_FILE))
    resume_file = property(lambda self: self.path(RESUME_FILE))
    best_file = property(lambda self: self.path(BEST_FILE))
    final_file = property(lambda self: self.path(FINAL_FILE))
    run_id_file = property(lambda self: self.path(RUN_ID_FILE))
    rows_file = property(lambda self: self.path(ROWS_FILE))
    rows_meta_file = property(lambda self: self.path(ROWS_META))
    done_file = property(lambda self: self.path(DONE_FILE))
    failed_file = property(lambda self: self.path(FAILED_FILE))
    block_file = property(lambda self: self.path(BLOCK_FILE))
    next_resume_file = property(lambda self: self.path(NEXT_RESUME_FILE))
    provenance_file = property(lambda self: self.path(PROVENANCE_FILE))

    def checkpoint(self, which: str) -> Path:
        """The policy a run is evaluated with: eval.checkpoint `best` or `final`."""
        return self.path(checkpoint_name(which))

    def mark_done(self, eval_run: str | None) -> None:
        """The sweep's mark: trained and evaluated (the evaluation's tracker run, if any)."""
        self.write(DONE_FILE, f"{eval_run or ''}\n")

    def mark_failed(self, message: str) -> None:
        """The sweep's mark: the job failed; its message is the summary's line."""
        self.write(FAILED_FILE, message)

    def clear_failed(self) -> None:
        self.failed_file.unlink(missing_ok=True)

    def failure(self) -> str | None:
        """The last line of the job's failure, or None if it is not marked failed."""
        try:
            lines = self.failed_file.read_text(encoding="utf-8", errors="replace").strip().splitlines()
        except FileNotFoundError:
            return None
        return (lines or ["(no message)"])[-1][:200]

    @property
    def state(self) -> str:
        """new | configured | training | trained | evaluated | failed, from the files alone."""
        for name, state in ((FAILED_FILE, "failed"), (DONE_FILE, "evaluated"),
                            (FINAL_FILE, "trained"), (RESUME_FILE, "training"),
                            (CONFIG_FILE, "configured")):
            if self.path(name).exists():  # the first file found, in this order, tells the state
                return state
        return "new"

    def write(self, name: str, data: str | bytes) -> Path:
        target = self.path(name)
        write_atomic(target, data)
        return target

    @contextlib.contextmanager
    def lock(self) -> Iterator[Run]:
        """Hold the folder for this process, or refuse in one line if another live process
        holds it. Re-entrant within a process."""
        self.dir.parent.mkdir(parents=True, exist_ok=True)
        self.lock_file.parent.mkdir(parents=True, exist_ok=True)
        key = str(self.lock_file)
        if key in _HELD:
            _HELD[key][1] += 1
            try:
                yield self
            finally:
                _HELD[key][1] -= 1
            return
        fd = os.open(key, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = _read_holder(fd)
            os.close(fd)
            raise SigmarlError(f"{self.dir} is in use by another sigmarl process{holder}; "
                               "wait for it to end (or stop it), then run the command again") from None
        try:
            os.ftruncate(fd, 0)
            os.write(fd, f"{os.getpid()} {socket.gethostname()}\n".encode())
        except OSError:
            pass  # the note only helps the message above; the lock is what counts
        _HELD[key] = [fd, 1]
        try:
            yield self
        finally:
            del _HELD[key]
            os.close(fd)  # releases the flock

    @property
    def locked_here(self) -> bool:
        return str(self.lock_file) in _HELD


def _read_holder(fd: int) -> str:
    try:
        pid_host = os.pread(fd, 200, 0).decode().split()
    except OSError:
        return ""
    return f" (pid {pid_host[0]} on {pid_host[1]})" if len(pid_host) == 2 else ""
