"""The CLI in child processes forked from a server that has imported the project once.

Tests that kill a command (SIGKILL at a crash point, SIGTERM) or race several need real
processes; a fresh interpreter would pay the imports (torch, torchrl, mlflow: seconds) each
time, a fork from multiprocessing's forkserver does not. The children start clean: the
server has imported modules but opened no store and run no torch code.
"""

from __future__ import annotations

import multiprocessing
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path

_context = None
PRELOAD = ["forked", "sigmarl.cli", "sigmarl.sweep", "sigmarl.training.loop",
           "sigmarl.evaluation.protocol", "sigmarl.cli.report", "mlflow", "pandas"]


def _ctx():
    global _context
    if _context is None:
        _context = multiprocessing.get_context("forkserver")
        _context.set_forkserver_preload(PRELOAD)
    return _context


def _child(args: list[str], cwd: str, env: dict[str, str], out: str, err: str,
           start_at: float, prelude: str | None) -> None:
    os.chdir(cwd)
    os.environ.pop("SIGMARL_CRASH_AT", None)
    os.environ.update(env)
    for fd, path in ((1, out), (2, err)):
        os.dup2(os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644), fd)
    while time.time() < start_at:
        time.sleep(0.002)
    if prelude:  # "module:function", called first (e.g. to make a library call misbehave)
        import importlib

        module, function = prelude.split(":")
        getattr(importlib.import_module(module), function)()
    from sigmarl.cli import main

    try:
        rc = main(args)
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
    os._exit(rc)


@dataclass
class Command:
    process: multiprocessing.process.BaseProcess
    out: Path
    err: Path

    @property
    def pid(self) -> int:
        return self.process.pid

    def wait(self, timeout: float = 300) -> int:
        self.process.join(timeout)
        return self.process.exitcode

    @property
    def stdout(self) -> str:
        return self.out.read_text()

    @property
    def stderr(self) -> str:
        return self.err.read_text()


_count = 0


def start(args: list[str], cwd: Path, start_at: float = 0.0, prelude: str | None = None,
          **env: str) -> Command:
    """`sigmarl <args>` in `cwd` with extra environment variables, e.g. SIGMARL_CRASH_AT;
    it waits for the clock to pass `start_at` and calls `prelude` before the command."""
    global _count
    _count += 1
    out, err = cwd / f".cli-{_count}.out", cwd / f".cli-{_count}.err"
    proc = _ctx().Process(target=_child, args=(args, str(cwd), env, str(out), str(err), start_at,
                                                     prelude))
    proc.start()
    return Command(proc, out, err)


def run(args: list[str], cwd: Path, prelude: str | None = None, **env: str) -> Command:
    """Start and wait; `returncode` is the exit code, or -signal if it was killed."""
    command = start(args, cwd, prelude=prelude, **env)
    command.returncode = command.wait()
    return command
