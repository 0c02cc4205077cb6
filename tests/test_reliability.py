"""A long study survives kills, races and broken stores: each case of docs/reliability.md.

Commands that must die (SIGKILL at a named crash point, SIGTERM) or race each other run the
real CLI in child processes (forked.py); everything else runs in this process.
"""

from __future__ import annotations

import http.server
import os
import shutil
import signal
import sqlite3
import subprocess
import sys
import textwrap
import threading
import time
from contextlib import contextmanager
from pathlib import Path

import forked
import pandas as pd
import pytest
import torch
from mlflow import MlflowClient

from sigmarl.cli import main
from sigmarl.compose import compose_config
from sigmarl.sweep.job import run_job
from sigmarl.tracking import connect
from sigmarl.training import checkpoint as ckpt
from sigmarl.training import train

SMOKE = ["ppo=smoke", "threads=1"]
TINY_EVAL = ["eval.n_sims=1", "eval.steps=5", "eval.scenarios=[Intersection]"]
CI_VARS = ("PYTEST_CURRENT_TEST", "CI", "GITHUB_ACTIONS", "MLFLOW_DISABLE_TELEMETRY",
           "DO_NOT_TRACK", "MLFLOW_HTTP_REQUEST_MAX_RETRIES", "MLFLOW_HTTP_REQUEST_TIMEOUT",
           "MLFLOW_HTTP_REQUEST_BACKOFF_FACTOR")


def _env(**extra: str) -> dict[str, str]:
    """The test's environment without what would hide a fault (MLflow turns telemetry off
    in CI and under pytest; retry settings are the project's own to choose)."""
    env = {k: v for k, v in os.environ.items() if k not in CI_VARS}
    return {**env, **extra}


def _cli(args: list[str], cwd: Path, **extra: str) -> forked.Command:
    """`sigmarl <args>` in a child process (see forked.py): returncode, stdout, stderr."""
    return forked.run(args, cwd, **extra)


def _runs(uri: str, experiment: str, kind: str | None = None):
    client = MlflowClient(uri)
    exp = client.get_experiment_by_name(experiment)
    if exp is None:
        return []
    flt = f"tags.kind = '{kind}'" if kind else ""
    return client.search_runs([exp.experiment_id], filter_string=flt)


@contextmanager
def read_only(path: Path):
    """Make a file or folder unwritable, also for root (immutable attribute), then restore."""
    if os.geteuid() != 0:
        mode = path.stat().st_mode
        path.chmod(0o555 if path.is_dir() else 0o444)
        try:
            yield
        finally:
            path.chmod(mode)
        return
    if shutil.which("chattr") is None or subprocess.run(["chattr", "+i", str(path)]).returncode:
        pytest.skip("running as root without chattr +i: cannot make a path read-only")
    try:
        yield
    finally:
        subprocess.run(["chattr", "-i", str(path)], check=True)


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """One tracked smoke training (3 iterations), the source of checkpoints below."""
    root = tmp_path_factory.mktemp("trained")
    uri = f"sqlite:///{root}/mlflow.db"
    cfg = compose_config([*SMOKE, f"tracking.tracking_uri={uri}", "tracking.experiment=t",
                          f"run_dir={root}/run"])
    result = train(cfg)
    return root, uri, result


# ---- 1. store creation race, half-migrated store -------------------------------------------


@pytest.mark.slow
def test_commands_started_together_on_a_new_store_do_not_race(tmp_path: Path) -> None:
    uri = f"sqlite:///{tmp_path}/store/mlflow.db"
    # a report of a results folder logs a report run: it creates the store it is pointed at
    # (a report read from MLflow creates none: with no store there is nothing to read)
    results = Path(__file__).parent / "data" / "results"
    go = time.time() + 3  # the three meet at the new store
    racers = [forked.start(["report", "--from", str(results), "--no-figures", "--out", f"out{k}",
                            f"tracking.tracking_uri={uri}", "tracking.experiment=nothing"], tmp_path, start_at=go)
              for k in range(3)]
    for racer in racers:
        # each finds a healthy store and logs its report run, not a migration error
        assert racer.wait() == 0, racer.stderr
    client = MlflowClient(tracking_uri=uri)
    assert len(client.search_runs([client.get_experiment_by_name("nothing").experiment_id])) == 3
    client = connect(compose_config([f"tracking.tracking_uri={uri}"]))
    assert client.create_experiment("after") is not None


def _stamp_older_schema(db: Path) -> None:
    """What an interrupted migration leaves: tables of a newer schema than the recorded version
    (here the oldest), so that migrating again fails on columns that already exist."""
    from alembic.script import ScriptDirectory
    from mlflow.store.db.utils import _get_alembic_config

    script = ScriptDirectory.from_config(_get_alembic_config(db_url=""))
    con = sqlite3.connect(db)
    con.execute("update alembic_version set version_num = ?", (script.get_bases()[0],))
    con.commit()
    con.close()


@pytest.mark.slow  # MLflow migrates a new store from scratch: 12 s
def test_a_half_migrated_empty_store_is_created_again(tmp_path: Path) -> None:
    # each command is a new process (MLflow caches an opened store per process)
    uri = f"sqlite:///{tmp_path}/mlflow.db"
    report = ["report", f"tracking.tracking_uri={uri}", "tracking.experiment=nothing"]
    # a new store, as a first run makes it (in its own process: MLflow caches an opened store)
    subprocess.run([sys.executable, "-c", "from sigmarl.compose import compose_config; from sigmarl.tracking "
                    f"import connect; connect(compose_config(['tracking.tracking_uri={uri}']))"], check=True)
    assert "no MLflow experiment" in _cli(report, tmp_path).stderr
    _stamp_older_schema(tmp_path / "mlflow.db")
    again = _cli(report, tmp_path)
    assert again.returncode == 2 and "half-created" in again.stderr
    assert "no MLflow experiment" in again.stderr
    client = connect(compose_config([f"tracking.tracking_uri={uri}"]))
    assert client.create_experiment("works") is not None


def test_a_half_migrated_store_with_runs_is_explained_and_kept(tmp_path: Path) -> None:
    uri = f"sqlite:///{tmp_path}/mlflow.db"
    client = connect(compose_config([f"tracking.tracking_uri={uri}"]))
    client.create_run(client.create_experiment("study"))
    _stamp_older_schema(tmp_path / "mlflow.db")
    before = (tmp_path / "mlflow.db").read_bytes()
    proc = _cli(["report", f"tracking.tracking_uri={uri}", "tracking.experiment=study"], tmp_path)
    err = proc.stderr.strip()
    assert proc.returncode == 2 and len(err.splitlines()) == 1, err
    assert str(tmp_path / "mlflow.db") in err and "mlflow db upgrade" in err
    assert (tmp_path / "mlflow.db").read_bytes() == before


# ---- 2. kill before the first checkpoint -------------------------------------------------


def test_a_folder_without_resume_point_restarts_without_asking(trained, tmp_path: Path) -> None:
    """What a kill in the first checkpoint_every iterations left before: best.pt, the config
    and the MLflow run id, but no checkpoint.pt. Training, resume and the sweep all go on."""
    root, _, _ = trained
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    for name in (ckpt.BEST_FILE, "config.yaml", "mlflow_run_id"):
        shutil.copy(root / "run" / name, run_dir / name)
    base = [*SMOKE, "tracking.enabled=false", f"run_dir={run_dir}"]
    assert main(["train", *base, "ppo.stop_after=1"]) == 0
    assert ckpt.load(run_dir / ckpt.RESUME_FILE)["iteration"] == 1
    (run_dir / ckpt.RESUME_FILE).unlink()
    assert main(["train", *base, "resume=true", "ppo.stop_after=1"]) == 0
    (run_dir / ckpt.RESUME_FILE).unlink()
    cfg = compose_config([*base, *TINY_EVAL])
    assert run_job(cfg) == "done"
    assert ckpt.load(run_dir / ckpt.FINAL_FILE)["iteration"] == 3


def test_a_resume_point_exists_before_the_first_iteration(tmp_path: Path) -> None:
    """Killed (SIGKILL) after iteration 1 with checkpoint_every=2: the sweep resumes it."""
    run_dir = tmp_path / "run"
    args = [*SMOKE, "tracking.enabled=false", f"run_dir={run_dir}", "ppo.checkpoint_every=2"]
    killed = _cli(["train", *args], tmp_path, SIGMARL_CRASH_AT="train:iteration:1")
    assert killed.returncode == -signal.SIGKILL
    assert ckpt.load(run_dir / ckpt.RESUME_FILE, resume=True)["iteration"] == 0
    assert run_job(compose_config([*args, *TINY_EVAL])) == "done"


# ---- 3. kill after final.pt ----------------------------------------------------------------


def test_a_rerun_after_a_kill_past_final_completes_the_mlflow_record(tmp_path: Path) -> None:
    uri = f"sqlite:///{tmp_path}/mlflow.db"
    args = [*SMOKE, f"tracking.tracking_uri={uri}", "tracking.experiment=k",
            f"run_dir={tmp_path}/run"]
    killed = _cli(["train", *args], tmp_path, SIGMARL_CRASH_AT="train:final")
    assert killed.returncode == -signal.SIGKILL
    (run,) = _runs(uri, "k")
    assert run.info.status == "RUNNING"
    assert main(["train", *args, "resume=true"]) == 0
    (run,) = _runs(uri, "k")
    assert run.info.status == "FINISHED"
    client = MlflowClient(uri)
    assert {a.path for a in client.list_artifacts(run.info.run_id)} == {
        "best.pt", "final.pt", "config.yaml"}
    steps = sorted(m.step for m in client.get_metric_history(run.info.run_id, "loss_objective"))
    assert steps == [1, 2, 3]


# ---- 4. signals ----------------------------------------------------------------------------


@pytest.mark.slow
def test_sigterm_ends_the_training_run_killed(tmp_path: Path) -> None:
    uri = f"sqlite:///{tmp_path}/mlflow.db"
    run_dir = tmp_path / "run"
    proc = forked.start(["train", *SMOKE, "ppo.iterations=200", f"tracking.tracking_uri={uri}",
                         "tracking.experiment=term", f"run_dir={run_dir}"], tmp_path)
    deadline = time.time() + 120
    while not (run_dir / ckpt.BEST_FILE).exists() and time.time() < deadline:
        time.sleep(0.1)
    os.kill(proc.pid, signal.SIGTERM)
    assert proc.wait() == 128 + signal.SIGTERM, proc.stderr
    assert "Traceback" not in proc.stderr
    (run,) = _runs(uri, "term")
    assert run.info.status == "KILLED"


@contextmanager
def _cli_signal_handlers(sigint=None):
    """The CLI's handlers for the test's duration (SIGINT first set to `sigint` if given)."""
    from sigmarl import errors
    from sigmarl.errors import handle_sigterm

    previous = signal.getsignal(signal.SIGTERM), signal.getsignal(signal.SIGINT)
    terminating = errors._terminating
    try:
        if sigint is not None:
            signal.signal(signal.SIGINT, sigint)
        handle_sigterm()
        yield
    finally:
        signal.signal(signal.SIGTERM, previous[0])
        signal.signal(signal.SIGINT, previous[1])
        errors._terminating = terminating


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT], ids=["SIGTERM", "SIGINT"])
def test_a_signal_inside_held_signals_is_raised_when_the_block_ends(signum) -> None:
    from sigmarl.errors import Terminated, held_signals

    expected = Terminated if signum == signal.SIGTERM else KeyboardInterrupt
    ran = []
    with _cli_signal_handlers(signal.default_int_handler), pytest.raises(expected) as caught:
        with held_signals():
            os.kill(os.getpid(), signum)
            ran.append("rest of the block")
        ran.append("after the block")
    assert ran == ["rest of the block"]
    assert (caught.type is Terminated) == (signum == signal.SIGTERM)


def test_a_second_signal_inside_held_signals_raises_at_once() -> None:
    from sigmarl.errors import Terminated, held_signals

    ran = []
    with _cli_signal_handlers(), pytest.raises(Terminated):
        with held_signals():
            os.kill(os.getpid(), signal.SIGTERM)
            ran.append("after the first")
            os.kill(os.getpid(), signal.SIGTERM)
            ran.append("after the second")
    assert ran == ["after the first"]


def test_a_block_in_another_thread_does_not_hold_the_main_threads_signal() -> None:
    """Only the main thread receives signals: a store call in a worker thread must not delay
    (nor receive) the main thread's interruption."""
    from sigmarl.errors import Terminated, held_signals

    inside, release = threading.Event(), threading.Event()

    def worker() -> None:
        with held_signals():
            inside.set()
            release.wait(10)

    thread = threading.Thread(target=worker)
    thread.start()
    try:
        inside.wait(10)
        with _cli_signal_handlers(), pytest.raises(Terminated):
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(1)  # the handler raises here, not when the worker's block ends
    finally:
        release.set()
        thread.join()


def test_an_ignored_sigint_stays_ignored() -> None:
    """A job started with SIGINT ignored (a shell's `cmd &`) is not made interruptible by it."""
    with _cli_signal_handlers(signal.SIG_IGN):
        assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
        os.kill(os.getpid(), signal.SIGINT)  # nothing happens


def sigterm_while_drawing() -> None:
    """Make matplotlib's savefig start its file, then receive SIGTERM (as from `timeout`)."""
    from matplotlib.figure import Figure

    def savefig(self, path, **kwargs):
        open(path, "wb").close()
        os.kill(os.getpid(), signal.SIGTERM)

    Figure.savefig = savefig


def _store_with_evaluations(folder: Path, experiment: str) -> str:
    """A store holding evaluation runs of M0 and M1 (hand-made rows); returns its URI."""
    from sigmarl.metrics import METRIC_COLUMNS
    from sigmarl.scenarios import scenario_names
    from sigmarl.tracking import experiment_id, records

    uri = f"sqlite:///{folder}/mlflow.db"
    client = connect(compose_config([f"tracking.tracking_uri={uri}"]))
    exp_id = experiment_id(client, experiment, create=True)
    for model in ("M0", "M1"):
        rows = pd.DataFrame([{"model": model, "obs": model, "seed": 0, "scenario": s,
                              "simulation": i, **{m: 0.1 * i for m in METRIC_COLUMNS}}
                             for s in scenario_names() for i in range(3)])
        records.log_evaluation(client, exp_id, rows, {"model": model, "seed": "0"}, {})
    return uri


def test_a_report_killed_while_drawing_leaves_no_empty_figure(tmp_path: Path) -> None:
    uri = _store_with_evaluations(tmp_path, "rep")
    out = tmp_path / "report"
    proc = forked.run(["report", "--out", str(out), f"tracking.tracking_uri={uri}",
                       "tracking.experiment=rep"], tmp_path, prelude=f"{__name__}:sigterm_while_drawing")
    assert proc.returncode == 128 + signal.SIGTERM, proc.stderr
    assert [p for p in out.rglob("*") if p.is_file() and p.stat().st_size == 0] == []
    assert not [r for r in _runs(uri, "rep", "report") if r.info.status == "RUNNING"]


# ---- 5. checkpoints are validated ------------------------------------------------------------


def _evaluate(path: Path, capsys) -> tuple[int, str]:
    rc = main(["evaluate", str(path), "--scenario", "Intersection", "eval.n_sims=1", "eval.steps=2",
               "tracking.enabled=false", f"--out={path.parent / 'rows.csv'}"])
    return rc, capsys.readouterr().err.strip()


@pytest.mark.parametrize("name", [ckpt.BEST_FILE, ckpt.FINAL_FILE, ckpt.RESUME_FILE])
def test_a_checkpoint_missing_a_policy_tensor_is_refused(trained, tmp_path, capsys, name) -> None:
    state = ckpt.load(trained[0] / "run" / name)
    dropped = sorted(state["policy"])[-1]
    del state["policy"][dropped]
    ckpt.save_atomic(state, tmp_path / name)
    rc, err = _evaluate(tmp_path / name, capsys)
    assert rc == 2 and len(err.splitlines()) == 1
    assert "missing" in err and dropped in err


def test_a_policy_tensor_of_another_shape_is_refused(trained, tmp_path, capsys) -> None:
    state = ckpt.load(trained[0] / "run" / ckpt.BEST_FILE)
    key = sorted(state["policy"])[0]
    state["policy"][key] = torch.cat([state["policy"][key], state["policy"][key]])
    ckpt.save_atomic(state, tmp_path / "best.pt")
    rc, err = _evaluate(tmp_path / "best.pt", capsys)
    assert rc == 2 and len(err.splitlines()) == 1 and "shape" in err and key in err


@pytest.mark.parametrize("dims", [{"obs_dim": 7}, {"n_agents": "four"}, {"action_low": None}])
def test_wrong_dims_are_one_line(trained, tmp_path, capsys, dims) -> None:
    state = ckpt.load(trained[0] / "run" / ckpt.FINAL_FILE)
    state["dims"] = {**state["dims"], **dims}
    ckpt.save_atomic(state, tmp_path / "final.pt")
    rc, err = _evaluate(tmp_path / "final.pt", capsys)
    assert rc == 2 and len(err.splitlines()) == 1 and "Traceback" not in err


def test_random_bytes_are_one_line_without_torchs_advice(tmp_path, capsys) -> None:
    (tmp_path / "best.pt").write_bytes(os.urandom(4096))
    rc, err = _evaluate(tmp_path / "best.pt", capsys)
    assert rc == 2 and len(err.splitlines()) == 1
    assert "unreadable" in err and "weights_only" not in err


def test_a_resume_point_whose_critic_lacks_a_tensor_is_refused(trained, tmp_path, capsys) -> None:
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    state = ckpt.load(trained[0] / "run" / ckpt.RESUME_FILE)
    state["iteration"] = 1
    del state["critic"][sorted(state["critic"])[0]]
    ckpt.save_atomic(state, run_dir / ckpt.RESUME_FILE)
    rc = main(["train", *SMOKE, "tracking.enabled=false", f"run_dir={run_dir}", "resume=true",
               f"tracking.tracking_uri={trained[1]}", "tracking.experiment=t"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1 and "critic" in err


def test_best_and_final_hold_the_policy_and_what_evaluation_needs(trained) -> None:
    run_dir = trained[0] / "run"
    resume = ckpt.load(run_dir / ckpt.RESUME_FILE)
    for name in (ckpt.BEST_FILE, ckpt.FINAL_FILE):
        state = ckpt.load(run_dir / name)
        assert {"critic", "optimizer", "rng"}.isdisjoint(state)
        assert {"policy", "config", "dims", "iteration", "best_reward"} <= state.keys()
        assert (run_dir / name).stat().st_size < (run_dir / ckpt.RESUME_FILE).stat().st_size / 2
    final = ckpt.load(run_dir / ckpt.FINAL_FILE)
    assert all(torch.equal(final["policy"][k], v) for k, v in resume["policy"].items())
    with pytest.raises(Exception, match="cannot resume from"):
        ckpt.load(run_dir / ckpt.FINAL_FILE, resume=True)


# ---- 6. tracking failures are fast and lose nothing --------------------------------------------


class _Unavailable(http.server.BaseHTTPRequestHandler):
    """A tracking server that answers every request with 503 and counts them."""

    count = 0

    def _answer(self) -> None:
        type(self).count += 1
        self.send_response(503)
        self.send_header("Content-Length", "0")
        self.end_headers()

    do_GET = do_POST = _answer

    def log_message(self, *args) -> None:
        pass


@pytest.fixture
def unavailable_server():
    handler = type("Handler", (_Unavailable,), {"count": 0})
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    yield f"http://127.0.0.1:{server.server_address[1]}", handler
    server.shutdown()


@pytest.mark.slow
@pytest.mark.parametrize("command", ["report", "evaluate", "sweep"])
def test_an_unavailable_store_fails_fast_before_any_work(trained, tmp_path, unavailable_server,
                                                         command) -> None:
    uri, handler = unavailable_server
    args = {"report": ["report"],
            "evaluate": ["evaluate", str(trained[0] / "run" / ckpt.FINAL_FILE), *TINY_EVAL,
                         "eval.scenarios=[CPM]"],
            "sweep": ["sweep", *SMOKE, "models=[M0]", f"hydra.sweep.dir={tmp_path}/multirun"],
            }[command]
    proc = _cli([*args, f"tracking.tracking_uri={uri}"], tmp_path,
                SIGMARL_CRASH_AT="eval:scenario:CPM")  # evaluating first would be killed
    err = proc.stderr.strip()
    assert proc.returncode == 2, err
    assert len(err.splitlines()) == 1 and uri in err
    assert 1 <= handler.count <= 3  # one request and at most two retries


def test_rows_saved_before_logging_are_logged_without_evaluating_again(trained, tmp_path) -> None:
    root, uri, _ = trained
    run_dir = tmp_path / "run"
    shutil.copytree(root / "run", run_dir)
    args = ["evaluate", str(run_dir / ckpt.BEST_FILE), *TINY_EVAL, f"tracking.tracking_uri={uri}",
            "tracking.experiment=t"]
    killed = _cli(args, tmp_path, SIGMARL_CRASH_AT="eval:rows")  # after the rows, before MLflow
    assert killed.returncode == -signal.SIGKILL
    # a tiny evaluation is not the run's study protocol: its rows go beside the study's (fault N1)
    [rows_file] = run_dir.glob("evaluation_rows*.csv")
    saved = pd.read_csv(rows_file)
    # evaluating again would be killed at its first scenario
    again = _cli(args, tmp_path, SIGMARL_CRASH_AT="eval:scenario:Intersection")
    assert again.returncode == 0, again.stderr
    runs = [r for r in _runs(uri, "t", "evaluation") if r.data.tags["checkpoint"].startswith(str(run_dir))]
    assert len(runs) == 1 and runs[0].info.status == "FINISHED"
    logged = pd.read_csv(MlflowClient(uri).download_artifacts(runs[0].info.run_id, "evaluation_rows.csv",
                                                              str(tmp_path)))
    pd.testing.assert_frame_equal(logged, saved)


def test_a_read_only_store_file_is_one_line_naming_it(tmp_path, capsys) -> None:
    uri = _store_with_evaluations(tmp_path, "x")
    report = ["report", "--no-figures", f"tracking.tracking_uri={uri}", "tracking.experiment=x",
              "--out", str(tmp_path / "report")]
    with read_only(tmp_path / "mlflow.db"):
        rc = main(report)  # it would log a report run
        err = capsys.readouterr().err.strip()
        assert rc == 2 and len(err.splitlines()) == 1 and str(tmp_path / "mlflow.db") in err
        # only reading it is fine
        assert main([*report, "tracking.enabled=false"]) == 0


def test_an_unwritable_working_folder_is_one_line_naming_it(tmp_path, capsys, monkeypatch) -> None:
    folder = tmp_path / "ro"
    folder.mkdir()
    monkeypatch.chdir(folder)
    with read_only(folder):
        rc = main(["train", *SMOKE, f"run_dir={tmp_path}/run"])  # default store: ./mlflow.db
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1 and str(folder) in err
    assert not (tmp_path / "run" / ckpt.RESUME_FILE).exists()


def test_an_unwritable_run_folder_is_one_line_and_leaves_no_run(tmp_path, capsys) -> None:
    uri = f"sqlite:///{tmp_path}/mlflow.db"
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    with read_only(run_dir):
        rc = main(["train", *SMOKE, f"tracking.tracking_uri={uri}", "tracking.experiment=u",
                   f"run_dir={run_dir}"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1 and str(run_dir) in err
    assert not [r for r in _runs(uri, "u") if r.info.status == "RUNNING"]


# ---- 7. no network at run time ----------------------------------------------------------------


AUDITED = textwrap.dedent("""
    import sys
    events = open(sys.argv[1], "w", buffering=1)

    def hook(event, args):
        if event in ("socket.connect", "socket.getaddrinfo", "socket.gethostbyname"):
            events.write(f"{event} {args[1:3] if event == 'socket.connect' else args[:2]}\\n")

    sys.addaudithook(hook)
    from sigmarl.cli import main
    rc = main(sys.argv[2:])
    import mlflow.telemetry.client as telemetry  # flush what a telemetry client queued
    if telemetry.get_telemetry_client() is not None:
        telemetry.get_telemetry_client().flush(terminate=True)
    sys.exit(rc)
""")


@pytest.mark.slow
def test_a_run_opens_no_socket(tmp_path: Path) -> None:
    """Training and evaluation against a SQLite store touch no network at all."""
    uri = f"sqlite:///{tmp_path}/mlflow.db"
    log = tmp_path / "sockets.txt"
    proc = subprocess.run(
        [sys.executable, "-c", AUDITED, str(log), "sweep", *SMOKE, "ppo.iterations=1", "models=[M0]",
         *TINY_EVAL, f"tracking.tracking_uri={uri}", f"hydra.sweep.dir={tmp_path}/multirun"],
        cwd=tmp_path, env=_env(), capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert log.read_text() == ""


def test_an_interruption_that_a_library_turns_into_its_own_error_still_counts():
    # Measured in a sweep: a SIGTERM that landed inside torchrl's MultiAgentMLP came out as
    # tensordict's RuntimeError, and the job was marked failed instead of interrupted.
    import torch
    from torchrl.modules import MultiAgentMLP

    from sigmarl.errors import Terminated, was_interrupted

    net = MultiAgentMLP(n_agent_inputs=4, n_agent_outputs=2, n_agents=3, centralised=False,
                        share_params=True, depth=1, num_cells=8)

    def signal_arrives(module, args):
        raise Terminated()

    net._empty_net.register_forward_pre_hook(signal_arrives)
    with pytest.raises(RuntimeError) as caught:
        net(torch.zeros(5, 3, 4))
    assert not isinstance(caught.value, KeyboardInterrupt)  # the library replaced it
    assert was_interrupted(caught.value)
    assert not was_interrupted(RuntimeError("a real failure"))
