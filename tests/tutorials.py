"""Run a tutorial page as written: its titled code blocks become files, its bash blocks'
commands run one after the other in a fresh folder, as `sigmarl` would run them in a shell.

A block preceded by `<!-- tutorial: not run (why) -->` is left out (an installation, a cluster).
A block with `title="path"` is written to that path. Every other bash line must be a `sigmarl`
command (after optional VAR=value assignments). `sweep` and `train` get a smoke budget appended,
so that a tutorial runs in seconds; nothing else of a command changes.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

DOCS = Path(__file__).resolve().parents[1] / "docs"
SMOKE = ["ppo.iterations=1", "ppo.frames_per_iteration=128", "ppo.epochs=1", "ppo.minibatch_size=64",
         "eval.n_sims=2", "eval.steps=40"]
_BLOCK = re.compile(r"^```(?P<lang>\w+)(?P<attrs>[^\n]*)\n(?P<body>.*?)^```[ \t]*$", re.M | re.S)


def blocks(page: str) -> list[tuple[str, str, str]]:
    """(language, title or "", body) of each block of a page that is run."""
    text = (DOCS / page).read_text(encoding="utf-8")
    out = []
    for m in _BLOCK.finditer(text):
        before = text[:m.start()].rstrip().rsplit("\n", 1)[-1]
        if before.startswith("<!-- tutorial: not run"):
            continue
        title = re.search(r'title="([^"]+)"', m.group("attrs"))
        out.append((m.group("lang"), title.group(1) if title else "", m.group("body")))
    return out


def commands(body: str) -> list[list[str]]:
    """The shell words of each command of a bash block (continuations joined, comments dropped)."""
    return [words for line in body.replace("\\\n", " ").splitlines() if (words := shlex.split(line, comments=True))]


def run_tutorial(page: str, cwd: Path, timeout: float = 900,
                 after: Callable[[int, subprocess.CompletedProcess], None] | None = None) -> list[subprocess.CompletedProcess]:
    """Write the page's files under `cwd` and run its commands there; each must succeed.
    `after(i, done)`, if given, runs after the i-th command, to check what that step left."""
    done = []
    for lang, title, body in blocks(page):
        if title:
            path = cwd / title
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(body, encoding="utf-8")
        elif lang in ("bash", "sh"):
            for words in commands(body):
                done.append(_run(words, cwd, timeout))
                if after:
                    after(len(done) - 1, done[-1])
    return done


def _run(words: list[str], cwd: Path, timeout: float) -> subprocess.CompletedProcess:
    env = dict(os.environ)
    while "=" in words[0] and not words[0].startswith("-"):
        name, value = words.pop(0).split("=", 1)
        if name == "PYTHONPATH":  # relative to the tutorial's folder, before what the tests use
            value = os.pathsep.join([str(cwd / value), env.get("PYTHONPATH", "")])
        env[name] = value
    assert words[0] == "sigmarl", f"a tutorial command that is not sigmarl's: {shlex.join(words)} (mark its block not run)"
    args = words[1:]
    command = next((a for i, a in enumerate(args) if not a.startswith("-") and (i == 0 or args[i - 1] != "--config-dir")), "")
    if command in ("sweep", "train"):
        args = [*args, *SMOKE]
    proc = subprocess.run([sys.executable, "-m", "sigmarl", *args], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=timeout)
    assert proc.returncode == 0, f"`{shlex.join(words)}` failed ({proc.returncode}):\n{proc.stderr[-3000:]}"
    return proc
