"""A killed report's staging folder does not outlive it (fifth reliability round)."""

from __future__ import annotations


def test_a_report_removes_the_staging_folders_killed_reports_left(tmp_path):
    """kill -9 runs no `finally`: the next report into the folder removes what it left, never a
    live report's."""
    import os
    import socket

    from sigmarl.cli.report import staged

    out = tmp_path / "report"
    host = socket.gethostname()
    older = out / ".staging-k2j4x9ab"  # an older version's, which named no owner
    dead = out / f".staging-999999999@{host}-a1b2c3d4"
    live = out / f".staging-{os.getpid()}@{host}-e5f6g7h8"
    elsewhere = out / ".staging-1@another-host-i9j0k1l2"
    for folder in (older, dead, live, elsewhere):
        (folder / "figures").mkdir(parents=True)
    with staged(out) as staging:
        assert staging.name.startswith(f".staging-{os.getpid()}@{host}-")
    assert sorted(p.name for p in out.iterdir()) == sorted([live.name, elsewhere.name])
