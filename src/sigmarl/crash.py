"""Named crash points for the crash-consistency test (tests/test_crash_consistency.py).

`point(name)` kills this process with SIGKILL, as a power cut or `kill -9` would, when the
environment variable SIGMARL_CRASH_AT equals `name`; otherwise it does nothing. The names
mark the instants between two writes whose order matters (a checkpoint and its metrics, a
file and its record in MLflow), so the test can stop a run exactly there.
"""

from __future__ import annotations

import os
import signal


def point(name: str) -> None:
    if os.environ.get("SIGMARL_CRASH_AT") == name:
        os.kill(os.getpid(), signal.SIGKILL)
