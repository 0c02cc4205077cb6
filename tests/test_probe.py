"""scripts/probe.py, the reliability round in one command, reports no failure: bad input is one
line with nothing left behind, a SIGKILLed training resumes whole, damaged files of its folder
are refused in one line or repaired from the checkpoint."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_the_probe_round_passes():
    done = subprocess.run([sys.executable, str(ROOT / "scripts" / "probe.py")], capture_output=True, text=True,
                          timeout=600)
    lines = done.stdout.splitlines()
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-2000:]
    assert [line for line in lines if line.startswith("FAIL")] == []
    passed = [line.split()[1] for line in lines if line.startswith("PASS")]
    assert {"kill9-resume", "F11-config", "F12-metrics", "F13-checkpoint", "agents"} <= set(passed)
    assert lines[-1] == f"{len(passed)} of {len(passed)} probes passed"
