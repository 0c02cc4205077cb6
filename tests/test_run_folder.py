"""The run folder's owner (`sigmarl.run`): whole-or-nothing writes, states read from the files,
and one live writer per folder, across processes and across a kill -9."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest

from sigmarl.errors import SigmarlError
from sigmarl.run import CONFIG_FILE, DONE_FILE, FINAL_FILE, RESUME_FILE, Run, write_atomic

HOLD = """
import sys, time
from sigmarl.run import Run
with Run(sys.argv[1]).lock():
    print("held", flush=True)
    time.sleep(600)
"""


def hold_in_another_process(folder: Path) -> subprocess.Popen:
    proc = subprocess.Popen([sys.executable, "-c", HOLD, str(folder)], stdout=subprocess.PIPE, text=True)
    assert proc.stdout.readline().strip() == "held"
    return proc


def test_a_failed_write_leaves_the_old_file_and_no_debris(tmp_path):
    target = tmp_path / "config.yaml"
    write_atomic(target, "old\n")

    def half_then_fail(f):
        f.write(b"half of the new")
        raise OSError(28, "No space left on device")

    with pytest.raises(OSError):
        write_atomic(target, half_then_fail)
    assert target.read_text() == "old\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["config.yaml"]
    write_atomic(target, b"new\n")
    assert target.read_text() == "new\n" and oct(target.stat().st_mode & 0o777) == "0o644"


def test_state_follows_the_files(tmp_path):
    run = Run(tmp_path / "M0" / "seed0")
    assert run.state == "new"
    for name, state in [(CONFIG_FILE, "configured"), (RESUME_FILE, "training"), (FINAL_FILE, "trained"),
                        (DONE_FILE, "evaluated")]:
        run.write(name, "x")
        assert run.state == state


def test_a_second_process_is_refused_in_one_line_and_the_lock_dies_with_its_holder(tmp_path):
    folder = tmp_path / "M0" / "seed0"
    holder = hold_in_another_process(folder)
    try:
        with pytest.raises(SigmarlError, match=rf"in use by another sigmarl process \(pid {holder.pid} on "):
            with Run(folder).lock():
                pass
    finally:
        holder.send_signal(signal.SIGKILL)
        holder.wait()
    with Run(folder).lock() as run:  # the kernel released it with its holder
        with Run(folder).lock():  # re-entrant within a process
            assert run.locked_here
    assert not Run(folder).locked_here
    assert not folder.exists()  # taking the lock creates nothing inside the run folder


def test_every_spelling_of_one_folder_is_one_writer(tmp_path, monkeypatch, capsys):
    """A symlink to the folder, a `..` path through it and a relative path take the folder's
    one lock: train and evaluate are refused while another process holds it."""
    from sigmarl.cli import main

    real = tmp_path / "runs" / "real"
    real.mkdir(parents=True)
    (tmp_path / "link").symlink_to(real)
    monkeypatch.chdir(tmp_path)
    holder = hold_in_another_process(real)
    try:
        for spelling in (tmp_path / "link", real / ".." / "real", Path("runs/real")):
            with pytest.raises(SigmarlError, match="in use by another sigmarl process"):
                with Run(spelling).lock():
                    pass
        rc = main(["train", "ppo=smoke", "tracking.enabled=false", "run_dir=link", "resume=true"])
        assert rc == 2 and "is in use by another sigmarl process" in capsys.readouterr().err
    finally:
        holder.kill()
        holder.wait()
    assert sorted(p.name for p in (tmp_path / "runs").iterdir()) == [".real.lock", "real"]
    assert not list(real.iterdir())


def test_train_refuses_a_folder_another_process_writes(tmp_path, capsys):
    from sigmarl.cli import main

    run_dir = tmp_path / "run"
    holder = hold_in_another_process(run_dir)
    try:
        rc = main(["train", "ppo=smoke", "tracking.enabled=false", f"run_dir={run_dir}"])
    finally:
        holder.kill()
        holder.wait()
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1 and "is in use by another sigmarl process" in err
    assert not run_dir.exists()


def _sweep(root: Path, store: str, iterations: int) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "sigmarl.cli", "sweep", "study=quick", "models=[M0]", "ppo=smoke",
         f"ppo.iterations={iterations}", "ppo.checkpoint_every=1", "eval.n_sims=1", "eval.steps=5",
         "eval.scenarios=[Roundabout]", store, f"runs_root={root}/runs", "hydra.launcher.n_jobs=1"],
        cwd=root, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)


def _finished_evaluations(store: str) -> int:
    from mlflow.tracking import MlflowClient

    client = MlflowClient(store.split("=", 1)[1])
    exp = client.get_experiment_by_name("sigmarl-quick")
    runs = client.search_runs([exp.experiment_id], "tags.kind = 'evaluation' and attributes.status = 'FINISHED'")
    return len(runs)


@pytest.mark.slow
def test_kill_9_of_a_sweep_ends_its_workers_and_a_rerun_converges(tmp_path):
    """The probe's worst case: kill -9 of the sweep's main process left its joblib workers
    training for over an hour, and a re-run trained the same folders beside them."""
    store = f"tracking.tracking_uri=sqlite:///{tmp_path}/mlflow.db"
    run = tmp_path / "runs" / "M0" / "seed0"
    sweep = _sweep(tmp_path, store, 12)
    deadline = time.time() + 300
    while not (run / RESUME_FILE).exists() and time.time() < deadline:
        time.sleep(0.2)
    assert (run / RESUME_FILE).exists(), sweep.stderr.read() if sweep.poll() is not None else "no checkpoint"
    os.kill(sweep.pid, signal.SIGKILL)
    sweep.wait()
    # the worker notices within its poll (2 s) and ends, interrupted and resumable
    deadline = time.time() + 60
    while time.time() < deadline:
        try:
            with Run(run).lock():
                break
        except SigmarlError:
            time.sleep(0.5)
    else:
        pytest.fail("the worker still holds the run folder a minute after its sweep died")
    rerun = _sweep(tmp_path, store, 12)
    out, err = rerun.communicate(timeout=900)
    assert rerun.returncode == 0, err[-2000:]
    metrics = pd.read_csv(run / "metrics.csv")
    assert list(metrics["iteration"]) == list(range(1, 13))  # one record per iteration
    assert _finished_evaluations(store) == 1


@pytest.mark.slow
def test_two_sweeps_at_once_train_each_folder_once(tmp_path):
    store = f"tracking.tracking_uri=sqlite:///{tmp_path}/mlflow.db"
    first, second = _sweep(tmp_path, store, 6), _sweep(tmp_path, store, 6)
    results = [p.communicate(timeout=900) for p in (first, second)]
    codes = sorted([first.returncode, second.returncode])
    assert codes[0] == 0, results
    busy = [err for _, err in results if "in use by another sigmarl process" in err]
    run = tmp_path / "runs" / "M0" / "seed0"
    metrics = pd.read_csv(run / "metrics.csv")
    assert list(metrics["iteration"]) == list(range(1, 7))
    assert _finished_evaluations(store) == 1
    if busy:  # the one that lost says so and leaves the job unfinished, not failed
        assert codes[1] == 1 and not (run / "failed.txt").exists()
    # a third sweep repairs nothing because nothing is broken: it finds the job done
    third = _sweep(tmp_path, store, 6)
    out, err = third.communicate(timeout=600)
    assert third.returncode == 0 and "trained and evaluated" in out
    assert _finished_evaluations(store) == 1


def test_a_resume_that_would_compute_in_another_precision_is_refused(tmp_path):
    """`ppo.precision=auto` resolves per machine; the resolved value is recorded in the
    checkpoint, and a resume on a machine that resolves it otherwise says so instead of silently
    switching precision. Device and threads may change."""
    import torch

    from sigmarl.compose import compose_config
    from sigmarl.training.checkpoint import save_atomic
    from sigmarl.training.loop import resolved_settings, train
    from sigmarl.training.ppo_loss import resolve_precision

    overrides = ["ppo=smoke", "ppo.iterations=2", "ppo.precision=auto", "tracking.enabled=false",
                 f"run_dir={tmp_path}/run"]
    cfg = compose_config([*overrides, "ppo.stop_after=1"])
    assert not train(cfg).finished
    path = tmp_path / "run" / RESUME_FILE
    state = torch.load(path, weights_only=False)
    here = resolve_precision(cfg)
    assert state["resolved"] == resolved_settings(cfg) == {"precision": here, "device": "cpu", "threads": 1}
    state["resolved"]["precision"] = {"fp32": "bf16", "bf16": "fp32"}[here]  # as another machine ran it
    save_atomic(state, path)  # saved with its checksum, as that machine would have
    with pytest.raises(SigmarlError, match=f"it trained in {state['resolved']['precision']} and this machine "
                                           f"resolves ppo.precision to {here}"):
        train(compose_config([*overrides, "resume=true"]))
    state["resolved"] = {"precision": here, "device": "cpu", "threads": 3}  # other threads: fine
    save_atomic(state, path)
    assert train(compose_config([*overrides, "resume=true"])).finished


def _ctrl_c_reaches_it() -> None:
    """A suite started as a shell's `cmd &` runs with SIGINT ignored, which its processes inherit
    (and keep, as sigmarl does on purpose): the sweep here starts as from a terminal."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


@pytest.mark.slow
@pytest.mark.parametrize("how", ["ctrl-c to the group", "sigterm to the main process", "sigkill to a worker"])
def test_an_interrupted_parallel_sweep_leaves_no_training_run_running(tmp_path, how):
    """F16: loky ends its workers when the sweep is interrupted, before they can end their MLflow
    runs; the sweep's main process ends those runs KILLED (resumable), as the workers would.
    F17: a worker lost to SIGKILL (the OOM killer) leaves no run RUNNING either, and is one line
    before the summary, not joblib's traceback."""
    from mlflow.tracking import MlflowClient

    store = f"tracking.tracking_uri=sqlite:///{tmp_path}/mlflow.db"
    sweep = subprocess.Popen(
        [sys.executable, "-m", "sigmarl.cli", "sweep", "study=quick", "models=[M0]", "seeds=[0,1]", "ppo=smoke",
         "ppo.iterations=40", "ppo.checkpoint_every=1", "eval.n_sims=1", "eval.steps=5", "eval.scenarios=[Roundabout]",
         store, f"runs_root={tmp_path}/runs", "hydra.launcher.n_jobs=2"],
        cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
        preexec_fn=_ctrl_c_reaches_it)
    runs = [tmp_path / "runs" / "M0" / f"seed{k}" for k in (0, 1)]
    deadline = time.time() + 300
    while not all((r / RESUME_FILE).exists() for r in runs) and time.time() < deadline:
        time.sleep(0.2)
    assert all((r / RESUME_FILE).exists() for r in runs), sweep.stderr.read() if sweep.poll() is not None else ""
    if how == "ctrl-c to the group":
        os.killpg(sweep.pid, signal.SIGINT)
    elif how == "sigterm to the main process":
        os.kill(sweep.pid, signal.SIGTERM)
    else:  # the worker training seed 1 wrote its pid into the folder's lock file
        os.kill(int((runs[1].parent / ".seed1.lock").read_text().split()[0]), signal.SIGKILL)
    out, err = sweep.communicate(timeout=300)
    assert sweep.returncode != 0
    if how == "sigkill to a worker":  # F17: one line and the summary, no joblib traceback
        assert "a worker process died" in err and "Traceback" not in err, err[-2000:]
        assert "while training one of M0/seed0, M0/seed1" in err, err[-2000:]
        assert "sweep summary:" in out and out.count("unfinished (run the sweep again to resume)") == 2, out
    client = MlflowClient(store.split("=", 1)[1])
    exp = client.get_experiment_by_name("sigmarl-quick")
    statuses = {r.info.run_id: r.info.status
                for r in client.search_runs([exp.experiment_id], "tags.kind = 'training'")}
    assert len(statuses) == 2 and "RUNNING" not in statuses.values(), statuses
