"""One tracking store for many machines: a real `mlflow server` on localhost, backed by
PostgreSQL (started here with pg_ctl in a temporary folder; SQLite where PostgreSQL or a
Python driver for it is not installed, or where it does not start), with a server-side
artifact root. A parallel sweep logs to it, `sigmarl report` builds its table from it, and two
processes logging at once lose nothing."""

from __future__ import annotations

import glob
import importlib.util
import os
import pwd
import shutil
import socket
import subprocess
import sys
import tempfile
import time
import urllib.request
from pathlib import Path

import pandas as pd
import pytest
from mlflow import MlflowClient

from sigmarl.cli import main

pytestmark = pytest.mark.slow


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def _pg_bin() -> Path | None:
    found = shutil.which("pg_ctl") or next(iter(sorted(glob.glob("/usr/lib/postgresql/*/bin/pg_ctl"))), None)
    return Path(found).resolve().parent if found else None


def _pg_driver() -> str | None:
    """The SQLAlchemy driver the server would use for PostgreSQL, if one is importable:
    `pg_ctl` on PATH says nothing about the Python side (`.[dev]` installs no driver)."""
    for module, driver in (("psycopg", "psycopg"), ("psycopg2", "psycopg2")):
        if importlib.util.find_spec(module) is not None:
            return driver
    return None


def _as_postgres(cmd: list[str]) -> list[str]:
    # PostgreSQL refuses to run as root; Debian's package creates the `postgres` user.
    return ["runuser", "-u", "postgres", "--", *cmd] if os.geteuid() == 0 else cmd


def _postgres_usable() -> tuple[Path, str] | None:
    """PostgreSQL's programs and a driver for them, or None (then the server uses SQLite)."""
    pg, driver = _pg_bin(), _pg_driver()
    if pg is None or driver is None or not (pg / "initdb").exists():
        return None
    if os.geteuid() == 0:
        try:
            pwd.getpwnam("postgres")
        except KeyError:
            return None
    return pg, driver


@pytest.fixture(scope="module")
def backend(tmp_path_factory):
    """A database URI for the server: a fresh PostgreSQL cluster where PostgreSQL and a Python
    driver for it are installed and the cluster starts, else SQLite."""
    sqlite = f"sqlite:///{tmp_path_factory.mktemp('db')}/mlflow.db"
    usable = _postgres_usable()
    if usable is None:
        yield sqlite
        return
    pg, driver = usable
    # not under pytest's root-only temp folder: the `postgres` user must reach it
    root = Path(tempfile.mkdtemp(prefix="sigmarl-pg"))
    data = root / "pgdata"
    if os.geteuid() == 0:
        shutil.chown(root, "postgres")
    port = _free_port()
    try:
        subprocess.run(_as_postgres([str(pg / "initdb"), "-D", str(data), "-U", "postgres", "--auth=trust",
                                     "-E", "UTF8"]), check=True, capture_output=True)
        subprocess.run(_as_postgres([str(pg / "pg_ctl"), "-D", str(data), "-w", "-l", str(root / "pg.log"),
                                     "-o", f"-p {port} -k {root} -c listen_addresses=127.0.0.1", "start"]),
                       check=True, capture_output=True)
    except (OSError, subprocess.CalledProcessError) as e:  # installed but not runnable here
        print(f"PostgreSQL did not start ({e}); the server uses SQLite", file=sys.stderr)
        shutil.rmtree(root, ignore_errors=True)
        yield sqlite
        return
    try:
        subprocess.run([str(pg / "createdb"), "-h", "127.0.0.1", "-p", str(port), "-U", "postgres",
                        "mlflow"], check=True, capture_output=True)
        yield f"postgresql+{driver}://postgres@127.0.0.1:{port}/mlflow"
    finally:
        subprocess.run(_as_postgres([str(pg / "pg_ctl"), "-D", str(data), "-m", "fast", "stop"]),
                       capture_output=True)
        shutil.rmtree(root, ignore_errors=True)


@pytest.fixture(scope="module")
def server(backend, tmp_path_factory):
    """`mlflow server` with the backend above and artifacts under one root it serves."""
    root = tmp_path_factory.mktemp("server")
    port = _free_port()
    log = root / "server.log"
    proc = subprocess.Popen(
        [sys.executable, "-m", "mlflow", "server", "--backend-store-uri", backend,
         "--artifacts-destination", str(root / "artifacts"), "--host", "127.0.0.1",
         "--port", str(port), "--workers", "2"],
        stdout=log.open("w"), stderr=subprocess.STDOUT, start_new_session=True)
    url = f"http://127.0.0.1:{port}"
    try:
        # a loaded machine takes minutes to start MLflow's workers: wait for an answer, not a count
        deadline, healthy = time.monotonic() + 600, False
        while not healthy and proc.poll() is None and time.monotonic() < deadline:
            try:
                healthy = urllib.request.urlopen(f"{url}/health", timeout=2).status == 200
            except OSError:
                time.sleep(0.5)
        assert healthy, log.read_text()[-3000:]
        yield url, root / "artifacts", backend
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, 15)
            try:
                proc.wait(timeout=10)
            except subprocess.TimeoutExpired:  # its workers drain slowly; nothing left to keep
                os.killpg(proc.pid, 9)
                proc.wait()


TINY = ["study=quick", "ppo.iterations=2", "ppo.frames_per_iteration=128", "ppo.epochs=1",
        "ppo.minibatch_size=64", "eval.n_sims=2", "eval.steps=20", "eval.scenarios=[Intersection]"]


def test_parallel_sweep_logs_to_the_server_and_report_reads_it(server, tmp_path, monkeypatch, capsys):
    url, artifacts, _ = server
    monkeypatch.chdir(tmp_path)
    uri = f"tracking.tracking_uri={url}"
    assert main(["sweep", *TINY, uri, "models=[M0,M4]", "hydra.launcher.n_jobs=2"]) == 0
    assert main(["report", "study=quick", uri]) == 0
    table = pd.read_csv(tmp_path / "reports" / "sigmarl-quick" / "table.csv")
    ours = table[table["source"] == "ours"]
    assert set(ours["scenario"]) == {"Intersection"} and {"M0", "M4"} <= set(ours.columns)
    client = MlflowClient(tracking_uri=url)
    exp = client.get_experiment_by_name("sigmarl-quick").experiment_id
    training = client.search_runs([exp], "tags.kind = 'training'")
    assert sorted(r.data.tags["model"] for r in training) == ["M0", "M4"]
    for run in training:  # every iteration's metrics arrived
        steps = [m.step for m in client.get_metric_history(run.info.run_id, "episode_reward_mean")]
        assert sorted(steps) == sorted(set(steps)) and len(steps) == 2
    # the artifacts went through the server into its artifact root, not into this folder
    assert list(artifacts.rglob("best.pt")) and list(artifacts.rglob("evaluation_rows.csv"))
    assert not (tmp_path / "mlartifacts").exists() and not (tmp_path / "mlflow.db").exists()


# Two processes log through sigmarl's MLflow tracker at the same moment: 150 iterations of three
# metrics each (one request per iteration, as training does) and an artifact.
LOGGER = """
import sys, time
from pathlib import Path
from sigmarl.compose import compose_config
from sigmarl.tracking import open_tracker
uri, seed, start, out = sys.argv[1], int(sys.argv[2]), float(sys.argv[3]), Path(sys.argv[4])
cfg = compose_config(["study=quick", f"tracking.tracking_uri={uri}", "tracking.experiment=concurrency",
                      f"seed={seed}"])
tracker = open_tracker(cfg).training_run()
time.sleep(max(0.0, start - time.time()))
for i in range(150):
    tracker.log_metrics([(i, {"a": seed + i, "b": 2.0 * i, "c": -float(i)})])
out.write_text(f"seed {seed}")
tracker.log_artifact(out)
tracker.finish()
print(tracker.run_id)
"""


def test_two_jobs_logging_at_once_lose_nothing(server, tmp_path):
    url = server[0]
    start = time.time() + 8  # both processes are past their imports by then
    procs = [subprocess.Popen([sys.executable, "-c", LOGGER, url, str(seed), str(start),
                               str(tmp_path / f"note{seed}.txt")], stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for seed in (0, 1)]
    outs = [p.communicate(timeout=300) for p in procs]
    assert all(p.returncode == 0 for p in procs), [o[1][-2000:] for o in outs]
    assert not any("warning" in o[1].lower() and "mlflow" in o[1].lower() for o in outs)
    client = MlflowClient(tracking_uri=url)
    for seed, (stdout, _) in enumerate(outs):
        run_id = stdout.strip().splitlines()[-1]
        expected = {"a": [seed + i for i in range(150)], "b": [2.0 * i for i in range(150)],
                    "c": [-float(i) for i in range(150)]}
        for key, values in expected.items():
            history = sorted((m.step, m.value) for m in client.get_metric_history(run_id, key))
            assert history == [(i, float(v)) for i, v in enumerate(values)]
        local = client.download_artifacts(run_id, f"note{seed}.txt", str(tmp_path / f"dl{seed}"))
        assert Path(local).read_text() == f"seed {seed}"
        assert client.get_run(run_id).info.status == "FINISHED"
