"""Progress of one job, readable wherever it runs.

On a terminal, and outside a sweep: a tqdm bar. Otherwise (output to a file or a pipe, or a job
of a sweep, whose parallel jobs would overwrite each other's bars): one plain line per update,
at most one every `min_interval` seconds (and always the first and the last), naming the job:

    M0 seed 0: train 12/250 (5%) reward 1.234 fps 412 | 3m10s, ETA 1h02m

Inside a Hydra job the lines go through `logging`, which Hydra's job logging sends to the
console and to the job's own log file (`<job folder>/sweep.log`); elsewhere to stderr.
"""

from __future__ import annotations

import logging
import os
import sys
import time

from sigmarl.resources import SWEEP_DIR

log = logging.getLogger("sigmarl.progress")


def plain_lines() -> bool:
    """Plain lines instead of a bar: inside a sweep job, or when stderr is not a terminal."""
    return SWEEP_DIR in os.environ or not sys.stderr.isatty()


def duration(seconds: float) -> str:
    """3m10s, 1h02m, 45s."""
    s = int(round(seconds))
    if s < 60:
        return f"{s}s"
    if s < 3600:
        return f"{s // 60}m{s % 60:02d}s"
    return f"{s // 3600}h{s % 3600 // 60:02d}m"


class Progress:
    def __init__(self, total: int, label: str, what: str, initial: int = 0, min_interval: float = 10.0,
                 enabled: bool = True) -> None:
        self.total, self.label, self.what, self.done = total, label, what, initial
        self.start_done, self.min_interval = initial, min_interval
        self.started = self.last = time.monotonic()
        self.bar = None
        self.enabled = enabled
        if enabled and not plain_lines():
            # lazy: tqdm only where a bar is drawn (start-up)
            from tqdm.auto import tqdm

            self.bar = tqdm(total=total, initial=initial, desc=f"{label}: {what}", dynamic_ncols=True, leave=False)

    def line(self, values: dict[str, str], now: float) -> str:
        elapsed = now - self.started
        done_here = self.done - self.start_done
        eta = elapsed / done_here * (self.total - self.done) if done_here else None
        shown = "".join(f" {k} {v}" for k, v in values.items())
        pct = 100 * self.done / self.total if self.total else 100.0
        return (f"{self.label}: {self.what} {self.done}/{self.total} ({pct:.0f}%){shown} | {duration(elapsed)}"
                + (f", ETA {duration(eta)}" if eta is not None and self.done < self.total else ""))

    def update(self, n: int = 1, **values: str) -> None:
        """`n` more done; `values` (already formatted) are shown beside the count."""
        self.done += n
        if not self.enabled:
            return
        if self.bar is not None:
            if values:
                self.bar.set_postfix(values, refresh=False)
            self.bar.update(n)
            return
        now = time.monotonic()
        first = self.done - n == self.start_done
        if first or self.done >= self.total or now - self.last >= self.min_interval:
            self.last = now
            emit(self.line(values, now))

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def emit(text: str, level: int = logging.INFO) -> None:
    """A line to the job's log in a sweep job (Hydra's job logging: console and
    `<job folder>/sweep.log`), else to stderr."""
    if SWEEP_DIR in os.environ:
        log.log(level, text)
    else:
        print(text, file=sys.stderr, flush=True)
