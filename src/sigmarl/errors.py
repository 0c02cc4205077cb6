"""Errors a user can cause (the CLI prints their message alone and exits non-zero), and the
interrupt policy: how an interruption reaches the code and what each kind leaves behind.

- SIGINT (Ctrl-C) and SIGTERM (`kill`, `timeout`, SLURM) are raised as KeyboardInterrupt and
  `Terminated` in the main thread, after any `held_signals` block. What runs then ends its
  tracker runs KILLED (`end_status`), removes nothing it wrote, and the command exits 130 or
  143 (`exit_code`). The run folder keeps its last `checkpoint.pt`.
- kill -9 (and the OOM killer) runs no handler: the tracker's runs stay RUNNING until a re-run
  reopens them, and the folder's lock goes with the process. Every file is written whole or
  not at all (`sigmarl.run.write_atomic`), except metrics.csv's last line, which may be cut.
- A resume reads only `checkpoint.pt` and the metrics.csv rows up to its iteration (later
  ones are computed again); a row missing at or before it is refused, never skipped.

Whatever catches a BaseException asks `interruption(e)` whether it is one of these: every
place that handles interruptions goes through the helpers below.
"""

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager


class SigmarlError(Exception):
    """A problem with the user's input (map file, config, checkpoint, tracking store)."""


class MapError(SigmarlError):
    """A map file or map definition that cannot be used; the message names file and element."""


class Terminated(KeyboardInterrupt):
    """SIGTERM (sent by `kill`, `timeout`, SLURM), raised like Ctrl-C: whatever handles an
    interruption (a run ended KILLED, a half-written file removed) handles it too."""


_terminating = False  # set by the SIGTERM handler (on_signal) before it raises
_holding = 0  # depth of `held_signals` blocks
_pending: int | None = None  # a signal that arrived inside one, raised when the block ends


def _interruption(signum: int) -> KeyboardInterrupt:
    return Terminated() if signum == signal.SIGTERM else KeyboardInterrupt()


def on_signal(signum: int, frame: object) -> None:
    """The handler of SIGTERM (and of SIGINT where Python's default one was in place): raise
    the interruption now, or at the end of the `held_signals` block that is running. A second
    signal inside the block raises at once: a stuck call still yields to a repeated kill."""
    global _pending, _terminating
    if signum == signal.SIGTERM:
        _terminating = True
    if _holding and _pending is None:
        _pending = signum
        return
    raise _interruption(signum)


@contextmanager
def held_signals() -> Iterator[None]:
    """Let a block finish before an interruption is raised. A signal that raised inside an
    MLflow store transaction left the SQLite connection holding its write lock (measured: a
    SIGTERM anywhere after the first INSERT of a `log_batch`), so the run could not be ended
    KILLED and MLflow printed the "database is locked" traceback. Signals reach the main thread
    only, so only its blocks hold them."""
    global _holding, _pending
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    _holding += 1
    try:
        yield
    finally:
        _holding -= 1
        if not _holding and _pending is not None:
            signum, _pending = _pending, None
            raise _interruption(signum)


def was_interrupted(error: BaseException) -> bool:
    """Whether `error` is, or stands in for, a Ctrl-C or SIGTERM.

    A signal raises at whatever line is running, and a library's cleanup can replace the
    KeyboardInterrupt with its own error (measured: a SIGTERM inside a torchrl module call
    surfaced as tensordict's "Converting a tensordict to boolean value is not permitted", and
    the job was marked failed). So the error's chain is searched, and a SIGTERM received by
    this process counts whatever error it turned into.
    """
    if _terminating:
        return True
    seen, todo = set(), [error]
    while todo:
        e = todo.pop()
        if e is None or id(e) in seen:
            continue
        if isinstance(e, KeyboardInterrupt):
            return True
        seen.add(id(e))
        todo += [e.__cause__, e.__context__]
    return False


def handle_sigterm() -> None:
    """Turn SIGTERM into `Terminated` (a KeyboardInterrupt) in this process's main thread, and
    let both it and Ctrl-C wait for the end of a `held_signals` block. SIGINT is taken over
    only from Python's default handler: a job started with it ignored (`cmd &`) keeps it so."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, on_signal)
        if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
            signal.signal(signal.SIGINT, on_signal)


def interruption(error: BaseException) -> KeyboardInterrupt | None:
    """The interruption `error` is or stands for (itself, or `Terminated` for a SIGTERM that a
    library turned into its own error), or None for a real failure."""
    if not was_interrupted(error):
        return None
    return error if isinstance(error, KeyboardInterrupt) else Terminated()


def raise_if_interrupted(error: BaseException) -> None:
    """Raise the interruption `error` stands for (chained to it); return if it is none."""
    stop = interruption(error)
    if stop is error:
        raise error
    if stop is not None:
        raise stop from error


def first_line(error: BaseException) -> str:
    """An error as one line: its type and the first line of its message (300 characters at most)."""
    text = str(error).strip().splitlines()
    return f"{type(error).__name__}: {text[0][:300]}" if text else type(error).__name__


def end_status(error: BaseException) -> str:
    """The tracker status of a run that `error` ended: KILLED (resumable) or FAILED."""
    return "KILLED" if was_interrupted(error) else "FAILED"


def exit_code(error: KeyboardInterrupt) -> tuple[str, int]:
    """What the command says and returns after an interruption: 128 + the signal's number."""
    return ("terminated", 128 + signal.SIGTERM) if isinstance(error, Terminated) else ("interrupted", 128 + signal.SIGINT)
