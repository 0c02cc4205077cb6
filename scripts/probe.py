"""A reliability round in one command: one named probe per fault of the reliability rounds
(F1-F18, G1-G11; issue 59's N1, N2, H1, H3, H4) and per promise of the run folder (kill -9 resume, blocks, sweeps, `evaluate`'s
lock, `report`), each run against the `sigmarl` CLI in its own temporary folder at a smoke
budget, PASS or FAIL per probe (exit code 1 if any fails).

    python scripts/probe.py               # the whole round (83 s on 2 idle cores)
    python scripts/probe.py F13 G1 kill9  # the probes named so: an exact name, or its fault (F6: both F6 probes)
    python scripts/probe.py --list F6     # the names a selection runs, without running them
    python scripts/probe.py --quick       # the probes that train nothing (bad input; a minute)

Each probe checks the property its name promises, not a stand-in: F13 that a NaN optimiser state
never reaches best.pt, `kill9-resume` that the resumed weights equal an uninterrupted run's.
Bad input must end in one line `sigmarl: error: ...`, exit code 2, and leave nothing behind. A new
round of probes starts by adding a `Probe` to one of the lists (`probe_input`, `probe_runs`,
`probe_sweeps`, `probe_results`).
"""

from __future__ import annotations

import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from probe_kit import Probe  # noqa: E402  (the folder on sys.path first)


def all_probes() -> list[Probe]:
    import probe_input
    import probe_limits
    import probe_results
    import probe_runs
    import probe_sweeps

    # every run-folder and sweep probe trains; of the input, limit and results probes, only those that say so
    probes = [*probe_input.PROBES, *probe_limits.PROBES,
              *(replace(p, trains=True) for p in (*probe_runs.PROBES, *probe_sweeps.PROBES)), *probe_results.PROBES]
    names = [p.name for p in probes]
    assert len(set(names)) == len(names), "two probes share a name"
    return probes


def select(probes: list[Probe], words: list[str]) -> list[Probe]:
    """The probes a word names exactly (its whole name, or its fault: `F1` is F1's, never F11's)."""
    unknown = [w for w in words if not any(w in (p.name, p.fault_id) for p in probes)]
    if unknown:
        raise SystemExit(f"probe.py: no probe named {', '.join(unknown)}; `--list` names them all")
    return [p for p in probes if not words or p.name in words or p.fault_id in words]


def _run_one(probe: Probe, root: Path) -> tuple[Probe, bool, str, float]:
    folder = root / probe.name
    folder.mkdir()
    started = time.monotonic()
    try:
        wrong = probe.check(folder)
    except Exception as e:  # a probe that cannot even be run is a failure, not a crash of the round
        wrong = f"the probe raised {type(e).__name__}: {e}"
    return probe, wrong is None, wrong or "holds", time.monotonic() - started


def main(argv: list[str]) -> int:
    listing, quick = "--list" in argv, "--quick" in argv
    words = [w for w in argv if w not in ("--list", "--quick")]
    chosen = [p for p in select(all_probes(), words) if not (quick and p.trains)]
    if listing:
        print("\n".join(p.name for p in chosen))
        return 0
    import probe_fixtures

    started = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="sigmarl-probe-") as tmp:
        probe_fixtures.ROOT = Path(tmp) / "fixtures"
        failed = 0
        # two at a time: each probe is mostly one process on one thread
        with ThreadPoolExecutor(max_workers=2) as pool:
            for probe, ok, said, seconds in pool.map(lambda p: _run_one(p, Path(tmp)), chosen):
                failed += not ok
                print(f"{'PASS' if ok else 'FAIL'}  {probe.name:26} {seconds:5.1f} s  {probe.fault}: {said}",
                      flush=True)
    print(f"{len(chosen) - failed} of {len(chosen)} probes passed in {time.monotonic() - started:.0f} s")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
