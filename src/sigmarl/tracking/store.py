"""Connecting to the MLflow tracking store: fast failures, one clear line, safe first use.

Every command connects here before it does any work, so a store that cannot be used ends
the command in seconds with one line naming the problem, not after hours of training or
minutes of evaluation:
- HTTP stores: a few seconds' timeout and two retries (MLflow's default is seven retries
  with exponential backoff, about four minutes);
- SQLite stores: the folder and the file are probed first (a read-only `mlflow.db` or an
  unwritable folder would otherwise cost two minutes of SQLAlchemy retries and pages of
  log output); the first use of a store is serialised by a file lock beside it
  (`mlflow.db.lock`), since two processes creating one store at the same moment both run
  the schema migration and break it; a store left half-migrated by such a race is
  recreated when it holds no runs, and explained otherwise;
- a new SQLite store is a copy of an empty one that MLflow created earlier (kept per MLflow
  version in `$SIGMARL_CACHE`, default `~/.cache/sigmarl/`): MLflow's own creation runs some
  fifty schema migrations, 5-9 s of CPU for every new store.
"""

from __future__ import annotations

import contextlib
import functools
import logging
import os
import shutil
import sqlite3
import sys
import tempfile
import time
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import TYPE_CHECKING
from urllib.parse import urlparse

from filelock import FileLock, Timeout

from sigmarl.errors import SigmarlError, held_signals

if TYPE_CHECKING:
    from sigmarl.config import Config

# read by MLflow's REST client at each request; the user's own settings win
os.environ.setdefault("MLFLOW_HTTP_REQUEST_MAX_RETRIES", "2")
os.environ.setdefault("MLFLOW_HTTP_REQUEST_BACKOFF_FACTOR", "1")
os.environ.setdefault("MLFLOW_HTTP_REQUEST_TIMEOUT", "10")
# A report downloads one small CSV per run: MLflow's progress bars would only be noise.
os.environ.setdefault("MLFLOW_ENABLE_ARTIFACTS_PROGRESS_BAR", "false")

LOCK_TIMEOUT_S = 300  # another process creating the store holds the lock for seconds


def tracking_uri(cfg: Config) -> str:
    """The configured URI, or MLflow's default (a SQLite `mlflow.db` in the working folder)."""
    if cfg.tracking.tracking_uri:
        return str(cfg.tracking.tracking_uri)
    # MLflow's own rule without importing it (seconds), while nothing in this process can have
    # called mlflow.set_tracking_uri: the variable, else ./mlflow.db unless ./mlruns holds runs
    if "mlflow" not in sys.modules and not Path("mlruns").exists():
        return os.environ.get("MLFLOW_TRACKING_URI") or f"sqlite:///{Path('mlflow.db').absolute()}"
    # lazy: MLflow (~1 s) only where a store is opened (start-up)
    from mlflow.tracking import get_tracking_uri

    return get_tracking_uri()


def missing_store(cfg: Config) -> Path | None:
    """The SQLite file of the configured store if it does not exist: a command that only reads
    finds nothing there, and should say so rather than create an empty store."""
    db = sqlite_file(tracking_uri(cfg))
    return db if db is not None and not db.exists() else None


def sqlite_file(uri: str) -> Path | None:
    """The database file of a `sqlite:///` URI (relative to the working folder), else None."""
    if urlparse(uri).scheme != "sqlite":
        return None
    db = uri.removeprefix("sqlite:///")
    if not db or db == ":memory:" or db == uri:
        return None
    return Path(db.split("?", 1)[0]).absolute()


def artifact_location(uri: str) -> str | None:
    """Artifacts of a local SQLite store go beside the database file, not into the cwd."""
    db = sqlite_file(uri)
    return None if db is None else (db.resolve().parent / "mlartifacts").as_uri()


def connect(cfg: Config, write: bool = True):
    """An MlflowClient on the configured store, checked by one query; SigmarlError if unusable.

    With `write=False` (a command that only reads), an existing SQLite store is opened as it
    is: a read-only copy of a study can still be reported on.
    """
    # creating or migrating a store is routine, not news: keep its INFO lines off the terminal
    for name in ("mlflow.store.db.utils", "alembic"):
        logging.getLogger(name).setLevel(logging.WARNING)
    uri = tracking_uri(cfg)
    db = sqlite_file(uri)
    if db is None or (not write and db.is_file()):
        return _open(uri)
    _probe_sqlite(db)

    try:
        with FileLock(str(db) + ".lock", timeout=LOCK_TIMEOUT_S):
            return _open_sqlite(uri, db)
    except Timeout as e:
        raise SigmarlError(f"another process has held {db}.lock for {LOCK_TIMEOUT_S} s; "
                           "if none is running, delete the lock file") from e


class SignalSafeClient:
    """An MlflowClient whose every call runs to its end before Ctrl-C or SIGTERM is raised
    (`errors.held_signals`): an interruption never tears a store transaction, and whatever
    the call wrote is whole. Attributes that are not methods pass through."""

    def __init__(self, client) -> None:
        self._client = client

    def __getattr__(self, name: str):
        value = getattr(self._client, name)
        if not callable(value):
            return value

        @functools.wraps(value)
        def held(*args, **kwargs):
            with held_signals():
                return value(*args, **kwargs)

        return held


def _first_line(e: BaseException) -> str:
    text = str(e).strip()
    return (text.splitlines()[0] if text else type(e).__name__)[:300]


def _open(uri: str):
    try:
        return _open_raw(uri)
    except Exception as e:  # bad URI, refused connection, HTTP errors after the retries
        raise SigmarlError(
            f"MLflow tracking store {uri!r} is unreachable or not usable: {_first_line(e)} "
            "(set tracking.tracking_uri=..., or tracking.enabled=false to run without it)"
        ) from e


def _probe_sqlite(db: Path) -> None:
    """The folder must be writable (SQLite writes its journal beside the file), the file too."""
    folder = db.parent
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise SigmarlError(f"cannot create folder {folder} for the MLflow store {db.name}: {e.strerror}") from e
    try:
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError as e:
        raise SigmarlError(
            f"folder {folder} of the MLflow store {db.name} is not writable ({e.strerror}); "
            "SQLite writes its journal there (set tracking.tracking_uri=sqlite:///<writable path>)"
        ) from e
    if db.exists():
        try:
            with open(db, "r+b"):
                pass
        except OSError as e:
            raise SigmarlError(f"MLflow store {db} is not writable ({e.strerror})") from e


def _open_sqlite(uri: str, db: Path):
    """Open (creating or migrating) the store; recreate it if a migration broke it empty."""
    new = not db.exists() or db.stat().st_size == 0
    if new and _seed_from_template(db):
        try:
            return _open_raw(uri)
        except Exception:  # a damaged template: forget it, and let MLflow create the store
            _forget_engines(db)
            _remove(db)
            if (template := _template()) is not None:
                template.unlink(missing_ok=True)
    try:
        client = _open_raw(uri)
    except Exception as e:
        runs = _user_records(db)
        if runs != 0 or "locked" in str(e):  # holds something (or is busy): never delete it
            held = "" if not runs else f"; it holds {runs} runs or experiments: back it up, " \
                f"then run `mlflow db upgrade {uri}`, or move it away to start a new store"
            raise SigmarlError(f"MLflow store {db} cannot be opened: {_first_line(e)}{held}") from e
        print(f"sigmarl: {db} was left half-created (an interrupted schema migration) and holds "
              "no runs; creating it again", file=sys.stderr)
        _forget_engines(db)
        _remove(db)
        try:
            client = _open_raw(uri)
        except Exception as again:
            raise SigmarlError(f"MLflow store {db} cannot be created: {_first_line(again)}") from again
        new = True
    if new:
        _save_template(db)
    return client


def _remove(db: Path) -> None:
    for suffix in ("", "-journal", "-wal", "-shm"):
        Path(f"{db}{suffix}").unlink(missing_ok=True)


def _template() -> Path | None:
    """Where an empty store of the installed MLflow version is kept; None if MLflow is not
    installed as a distribution (then its schema cannot be told apart by version)."""
    try:
        mlflow_version = version("mlflow")
    except PackageNotFoundError:
        return None
    root = os.environ.get("SIGMARL_CACHE") or Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "sigmarl"
    return Path(root) / f"mlflow-{mlflow_version}-empty.db"


def _seed_from_template(db: Path) -> bool:
    """Put a copy of the empty template store at `db` (caller holds the store's lock). Only its
    Default experiment differs between stores: its artifact folder (MLflow's default, `mlruns/0`
    in the working folder) and its creation time are set as MLflow would set them now."""
    template = _template()
    if template is None or not template.is_file():
        return False
    _drop_stale_saves(template)
    tmp = db.with_name(db.name + ".new")
    try:
        shutil.copyfile(template, tmp)
        now = int(time.time() * 1000)
        con = sqlite3.connect(tmp)
        try:
            with con:
                con.execute("update experiments set artifact_location = ?, creation_time = ?, last_update_time = ? "
                            "where experiment_id = 0", (str(Path.cwd() / "mlruns" / "0"), now, now))
        finally:
            con.close()
        os.replace(tmp, db)  # the store appears whole or not at all
    except (OSError, sqlite3.Error):
        tmp.unlink(missing_ok=True)
        return False
    return True


def _save_template(db: Path) -> None:
    """Keep a copy of the store MLflow has just created, while it still holds nothing but its
    Default experiment. A cache: any failure only means the next store is created by MLflow."""
    template = _template()
    if template is None or _user_records(db) != 0:
        return
    tmp = template.with_name(f"{template.name}.{os.getpid()}.tmp")
    try:
        template.parent.mkdir(parents=True, exist_ok=True)
        src, dst = sqlite3.connect(f"file:{db}?mode=ro", uri=True), sqlite3.connect(tmp)
        try:
            src.backup(dst)  # a consistent copy, whatever the journal holds
        finally:
            src.close()
            dst.close()
        os.replace(tmp, template)  # two processes saving at once each replace it whole
    except (OSError, sqlite3.Error):
        with contextlib.suppress(OSError):  # a cache folder that is not one (a file) cannot hold it either
            tmp.unlink(missing_ok=True)
    _drop_stale_saves(template)


STALE_SAVE_S = 3600  # a save takes milliseconds; a `.tmp` this old was left by a killed one


def _drop_stale_saves(template: Path) -> None:
    for old in template.parent.glob(f"{template.name}.*.tmp"):
        try:
            if time.time() - old.stat().st_mtime > STALE_SAVE_S:
                old.unlink()
        except OSError:
            pass  # another process removed or is replacing it


def _forget_engines(db: Path) -> None:
    """Close this process's connections to `db`: MLflow keeps one engine per URI, whose
    pooled connections would go on reading a deleted file."""
    # lazy: MLflow (~1 s) only where a store is opened (start-up)
    from mlflow.store.tracking.sqlalchemy_store import SqlAlchemyStore

    for key, engine in list(SqlAlchemyStore._engine_map.items()):
        if engine.url.database and Path(engine.url.database).absolute() == db:
            SqlAlchemyStore._engine_map.pop(key, None)
            engine.dispose()


def _open_raw(uri: str):
    """A client on `uri`, checked by one query (which raises if the store is unusable)."""
    # lazy: MLflow (~1 s) only where a store is opened (start-up)
    from mlflow import MlflowClient

    client = SignalSafeClient(MlflowClient(tracking_uri=uri))
    client.search_experiments(max_results=1)
    return client


def _user_records(db: Path) -> int | None:
    """Runs plus experiments other than MLflow's Default in the SQLite file; None if unreadable."""
    try:
        con = sqlite3.connect(f"file:{db}?mode=ro", uri=True, timeout=5)
        try:
            tables = {r[0] for r in con.execute("select name from sqlite_master where type='table'")}
            count = 0
            if "runs" in tables:
                count += int(con.execute("select count(*) from runs").fetchone()[0])
            if "experiments" in tables:
                count += int(con.execute(
                    "select count(*) from experiments where name != 'Default'").fetchone()[0])
            return count
        finally:
            con.close()
    except sqlite3.Error:
        return None


# MLflow 3's UI opens an experiment of this kind on its runs (not on GenAI traces)
KIND_TAG, KIND = "mlflow.experimentKind", "custom_model_development"


def experiment_id(client, name: str, create: bool = False) -> str | None:
    """The experiment's id; created (artifacts beside a SQLite store) if asked, else None."""
    exp = client.get_experiment_by_name(name)
    if exp is not None:
        return exp.experiment_id
    if not create:
        return None
    # lazy: MLflow (~1 s) only where a store is opened (start-up)
    from mlflow.exceptions import MlflowException

    try:
        return client.create_experiment(name, artifact_location=artifact_location(client.tracking_uri),
                                        tags={KIND_TAG: KIND})
    except MlflowException:  # another process created it in the meantime
        exp = client.get_experiment_by_name(name)
        if exp is None:
            raise
        return exp.experiment_id
