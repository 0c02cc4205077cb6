"""Probes of sweeps and reports with a real MLflow store: lost rows measured again, a sweep or
one of its workers killed (no run left RUNNING, one line saying what was cut short), seed
blocks extending a finished study, a report killed while logging, a report that would mislabel."""

from __future__ import annotations

import signal
from pathlib import Path

import probe_fixtures as fx
from probe_kit import SMOKE, TINY_EVAL, Probe, last_line, one_line, sigmarl, start, wait_for

# two seeds, two worker slots: each job is a loky worker, so that killing one spares the sweep
PARALLEL = ["sweep", "study=quick", "models=[M0]", "ppo=smoke", "threads=1", *TINY_EVAL, fx.STORE, "runs_root=runs",
            "hydra.launcher.n_jobs=2"]


def _statuses(folder: Path, kind: str) -> list[str]:
    from mlflow.tracking import MlflowClient

    client = MlflowClient(f"sqlite:///{folder / 'mlflow.db'}")
    found = []
    for exp in client.search_experiments():
        found += [r.info.status for r in client.search_runs([exp.experiment_id], f"tags.kind = '{kind}'")]
    return sorted(found)


def _none_running(folder: Path) -> str | None:
    running = {k: s.count("RUNNING") for k in ("training", "evaluation", "report") if (s := _statuses(folder, k))}
    return None if not any(running.values()) else f"runs left RUNNING: {running}"


def _lost_rows(folder: Path) -> str | None:
    fx.copy_of(fx.study)(folder)
    run = folder / fx.RUN
    weights = (run / "final.pt").read_bytes()
    (run / "evaluation_rows.csv").unlink()
    done = sigmarl(fx.STUDY, folder)
    if done.returncode != 0:
        return f"the re-run failed (rc {done.returncode}): {last_line(done)}"
    if not (run / "evaluation_rows.csv").exists():
        return "the lost rows were not measured again"
    return None if (run / "final.pt").read_bytes() == weights else "the re-run trained the finished seed again"


def _sigterm(folder: Path) -> str | None:
    sweep = start([*PARALLEL, "seeds=[0,1]", "ppo.iterations=40"], folder)
    if not wait_for(lambda: any((folder / "runs" / "M0").glob("seed*/checkpoint.pt"))):
        sweep.kill()
        return "no checkpoint within 300 s"
    sweep.send_signal(signal.SIGTERM)
    rc = sweep.wait(120)
    if rc != 143:
        return f"rc {rc} after SIGTERM, not 143"
    return _none_running(folder)


def _worker_killed(point: str, doing: str):
    def check(folder: Path) -> str | None:
        done = sigmarl([*PARALLEL, "seeds=[0]"], folder, SIGMARL_CRASH_AT=point)
        if done.returncode != 1:
            return f"rc {done.returncode}, not 1: {last_line(done)}"
        if "a worker process died" not in done.stderr or f"while {doing}" not in done.stderr:
            return f"the line does not say the worker died while {doing}: {last_line(done)}"
        if "Traceback" in done.stderr:
            return "a traceback on stderr"
        return _none_running(folder)
    return check


def _blocks_extend(folder: Path) -> str | None:
    base = ["sweep", "study=quick", "models=[M0]", *SMOKE, *TINY_EVAL, "runs_root=runs"]
    done = sigmarl([*base, "seeds=[0]"], folder)
    if done.returncode != 0:
        return f"the first sweep failed (rc {done.returncode}): {last_line(done)}"
    weights = (folder / fx.RUN / "final.pt").read_bytes()
    done = sigmarl([*base, "seeds=[0,1]", "sweep.seeds_per_job=2"], folder)
    if done.returncode != 0:
        return f"the block sweep failed (rc {done.returncode}): {last_line(done)}"
    seed0, seed1 = folder / fx.RUN, folder / "runs" / "M0" / "seed1"
    if (seed0 / "failed.txt").exists() or (seed0 / "final.pt").read_bytes() != weights:
        return "the finished seed 0 was marked failed or trained again"
    return None if (seed1 / "evaluation_rows.csv").exists() else "seed 1 was not trained and evaluated"


def _report_killed(folder: Path) -> str | None:
    fx.copy_of(fx.study)(folder)
    report = ["report", "study=quick", fx.STORE, "--no-figures", "--out", "report"]
    killed = sigmarl(report, folder, SIGMARL_CRASH_AT="report:logging")
    if killed.returncode != -9:
        return f"the report was not killed at its crash point (rc {killed.returncode})"
    done = sigmarl(report, folder)
    if done.returncode != 0:
        return f"the next report failed (rc {done.returncode}): {last_line(done)}"
    if not (folder / "report" / "table.md").exists():
        return "no table.md after the next report"
    statuses = _statuses(folder, "report")
    return None if statuses == ["FINISHED", "KILLED"] else f"report runs {statuses}, not one KILLED and one FINISHED"


def _mislabelled(folder: Path) -> str | None:
    """The quick study's 3-iteration M0 evaluated into the paper study's experiment must not be
    reported as the paper's M0."""
    fx.copy_of(fx.study)(folder)
    done = sigmarl(["evaluate", str(fx.RUN), fx.STORE, "tracking.experiment=sigmarl-ablation", *TINY_EVAL], folder)
    if done.returncode != 0:
        return f"the evaluation failed (rc {done.returncode}): {last_line(done)}"
    return one_line(sigmarl(["report", "study=paper", fx.STORE, "--no-figures", "--out", "report"], folder),
                    "fingerprint")


PROBES = [
    Probe("F10-lost-rows", "a finished run's evaluation rows deleted, then the sweep again", _lost_rows),
    Probe("F16-sweep-sigterm", "SIGTERM to a parallel sweep's main process mid-training", _sigterm),
    Probe("F17-worker-killed", "a sweep worker killed (SIGKILL) while training",
          _worker_killed("train:checkpoint:2", "training")),
    Probe("G2-worker-killed-evaluating", "a sweep worker killed (SIGKILL) while logging its evaluation",
          _worker_killed("eval:logging", "evaluating")),
    Probe("G3-blocks-extend", "a finished seed, then a block sweep over it and a new seed", _blocks_extend),
    Probe("report-kill9", "a report killed (SIGKILL) while logging, then the report again", _report_killed),
    Probe("report-mislabel", "a quick-budget M0 evaluated into the paper study's experiment, then its report",
          _mislabelled),
]
