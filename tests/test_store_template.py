"""A new SQLite store copied from the cached empty one is the store MLflow itself creates."""

from __future__ import annotations

import os
import sqlite3
import time
from pathlib import Path

import pytest
from mlflow import MlflowClient

from sigmarl.compose import compose_config
from sigmarl.tracking import connect


def _connect(db: Path):
    return connect(compose_config([f"tracking.tracking_uri=sqlite:///{db}"]))


def _rows(db: Path, query: str) -> list[tuple]:
    con = sqlite3.connect(db)
    try:
        return con.execute(query).fetchall()
    finally:
        con.close()


def _schema(db: Path) -> list[tuple]:
    """Tables and indexes with their definitions; a definition's lines as a set, since MLflow
    writes a table's constraints in an order that changes from one process to the next."""
    rows = _rows(db, "select type, name, tbl_name, sql from sqlite_master order by type, name")
    return [(*r[:3], sorted(line.strip().rstrip(",") for line in (r[3] or "").splitlines())) for r in rows]


DEFAULT = "select * from experiments where experiment_id = 0"


@pytest.fixture
def cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv("SIGMARL_CACHE", str(tmp_path / "cache"))
    monkeypatch.chdir(tmp_path)
    return tmp_path / "cache"


def test_a_store_from_the_template_equals_the_one_mlflow_creates(tmp_path: Path, cache: Path) -> None:
    _connect(tmp_path / "first" / "mlflow.db")  # MLflow creates it; it becomes the template
    (template,) = cache.glob("mlflow-*-empty.db")
    before = int(time.time() * 1000)
    copied = _connect(tmp_path / "copied" / "mlflow.db")
    after = int(time.time() * 1000)
    MlflowClient(tracking_uri=f"sqlite:///{tmp_path / 'own' / 'mlflow.db'}").search_experiments()

    copied_db, own_db = tmp_path / "copied" / "mlflow.db", tmp_path / "own" / "mlflow.db"
    assert _schema(copied_db) == _schema(own_db)
    assert _rows(copied_db, "select * from alembic_version") == _rows(own_db, "select * from alembic_version")
    columns = [r[1] for r in _rows(own_db, "pragma table_info(experiments)")]
    times = [columns.index("creation_time"), columns.index("last_update_time")]
    (mine,), (theirs,) = _rows(copied_db, DEFAULT), _rows(own_db, DEFAULT)
    assert [v for k, v in enumerate(mine) if k not in times] == [v for k, v in enumerate(theirs) if k not in times]
    assert all(before <= mine[k] <= after for k in times)
    assert str(tmp_path / "mlruns" / "0") in mine  # MLflow's default artifact folder, from here

    # and it works as a store
    run = copied.create_run(copied.create_experiment("study"))
    copied.log_metric(run.info.run_id, "reward", 1.5, step=3)
    assert copied.get_metric_history(run.info.run_id, "reward")[0].value == 1.5
    assert copied.get_experiment_by_name("study") is not None
    assert template.is_file() and not list(cache.glob("*.tmp"))


def test_a_store_is_copied_from_the_template_and_a_damaged_template_is_replaced(tmp_path: Path, cache: Path) -> None:
    _connect(tmp_path / "first" / "mlflow.db")
    (template,) = cache.glob("mlflow-*-empty.db")
    con = sqlite3.connect(template)
    con.execute("create table marker (x)")  # only a copy of the template can hold this
    con.commit()
    con.close()
    _connect(tmp_path / "copied" / "mlflow.db")
    assert ("marker",) in _rows(tmp_path / "copied" / "mlflow.db", "select name from sqlite_master")

    template.write_bytes(b"not a database" * 100)
    client = _connect(tmp_path / "after" / "mlflow.db")  # MLflow creates it, and it is the new template
    assert client.create_experiment("works") is not None
    assert _rows(template, "select name from experiments") == [("Default",)]
    assert ("marker",) not in _rows(template, "select name from sqlite_master")


def test_a_save_left_by_a_killed_process_is_dropped_later(tmp_path: Path, cache: Path) -> None:
    _connect(tmp_path / "first" / "mlflow.db")
    (template,) = cache.glob("mlflow-*-empty.db")
    stale, live = Path(f"{template}.999999.tmp"), Path(f"{template}.999998.tmp")
    stale.write_bytes(b"half a store")
    live.write_bytes(b"being written")
    hours_ago = time.time() - 2 * 3600
    os.utime(stale, (hours_ago, hours_ago))
    _connect(tmp_path / "second" / "mlflow.db")
    assert not stale.exists() and live.exists()  # a save in progress is never touched
