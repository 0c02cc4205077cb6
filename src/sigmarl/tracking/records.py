"""The study's evaluation and report runs in MLflow: writing them and finding them again.

One evaluation run per trained model (tag kind=evaluation, per-simulation rows as a CSV
artifact, scenario means as metrics), one report run per `sigmarl report`, and the reads
the report needs. An evaluation run that a kill left RUNNING is deleted before its job is
logged again, so the store ends with one evaluation run per job and none left RUNNING; a
report run a kill left RUNNING is ended KILLED by the next report.
"""

from __future__ import annotations

import os
import socket
import tempfile
import time
from collections import Counter
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

from sigmarl import crash
from sigmarl.ablation import TIMINGS
from sigmarl.errors import SigmarlError, end_status
from sigmarl.metrics import CS, METRIC_COLUMNS, METRICS, TABLE_DIGITS
from sigmarl.readers import read_run_config
from sigmarl.run import REWARD_COLUMN, ROWS_FILE, Run
from sigmarl.tracking.store import experiment_id

if TYPE_CHECKING:  # pandas is imported where rows are read: a sweep's quick checks need only eval_key
    import pandas as pd

ROWS_ARTIFACT = ROWS_FILE
# The process that logs a report run, so that a later report can tell a dead one's run
OWNER_HOST, OWNER_PID = "sigmarl.host", "sigmarl.pid"
# An evaluation run's scenario means, in the table's units with the unit in the name (the rows
# artifact keeps the rows' own units: collision rates as fractions of steps)
_SUFFIX = {"percent": "pct", "cm": "cm", "m/s": "mps"}
METRIC_NAMES = {m.name: f"{m.name}_{_SUFFIX.get(m.unit, m.unit)}" for m in METRICS}
METRIC_SCALE = {m.name: m.scale for m in METRICS if m.scale != 1.0}


def evaluation_runs(client, exp_id: str, train_run_id: str, key: str, status: str):
    """The evaluation runs of a training run under an evaluation protocol, in `status`."""
    return client.search_runs(
        [exp_id],
        filter_string=(
            f"tags.kind = 'evaluation' and tags.train_run_id = '{train_run_id}' "
            f"and tags.eval_key = '{key}' and attributes.status = '{status}'"
        ),
    )


def finished_evaluation(client, exp_id: str, train_run_id: str, key: str):
    """The FINISHED evaluation run of a training run under an evaluation protocol, if any."""
    runs = evaluation_runs(client, exp_id, train_run_id, key, "FINISHED")
    return runs[0] if runs else None


def log_evaluation(client, exp_id: str, rows: pd.DataFrame, tags: dict[str, str],
                   params: dict[str, str]) -> str:
    """One evaluation run: rows as a CSV artifact, per-scenario means as metrics.

    Runs of the same training run and protocol that an earlier attempt left are deleted first:
    a killed one's (RUNNING, FAILED, KILLED) hold part of what this run logs, and a FINISHED one
    is what this run replaces (`sigmarl evaluate` twice: one evaluation run).
    """
    # lazy: MLflow (~1 s) and pandas only where a store or rows are used
    from mlflow.entities import Metric, Param

    if tags.get("train_run_id"):
        for status in ("RUNNING", "FAILED", "KILLED", "FINISHED"):
            for old in evaluation_runs(client, exp_id, tags["train_run_id"], tags["eval_key"], status):
                client.delete_run(old.info.run_id)
    parent = _parent_tag(client, exp_id, tags.get("train_run_id"))
    run = client.create_run(exp_id, run_name=f"eval-{tags.get('model', 'policy')}-seed{tags.get('seed', '')}",
                            tags={"kind": "evaluation", **tags, **parent})
    rid = run.info.run_id
    with _ended(client, rid):
        means = rows.groupby("scenario")[METRIC_COLUMNS].mean()
        now = int(time.time() * 1000)
        # at the table's precision: a float32 mean's tail (27.500000596046448) is noise, and the
        # rows artifact keeps every value whole
        metrics = [Metric(f"{scenario}/{METRIC_NAMES.get(metric, metric)}",
                          round(float(value) * METRIC_SCALE.get(metric, 1.0), TABLE_DIGITS), now, 0)
                   for scenario, row in means.iterrows() for metric, value in row.items()]
        client.log_batch(rid, metrics=metrics, params=[Param(k, v) for k, v in params.items()])
        crash.point("eval:logging")
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / ROWS_ARTIFACT
            rows.to_csv(path, index=False)
            client.log_artifact(rid, str(path))
    return rid


def _parent_tag(client, exp_id: str, train_run_id: str | None) -> dict[str, str]:
    """MLflow's tag that nests a run under another (its UI shows an evaluation under its
    training run), where the training run is in the same experiment (the UI nests only there)."""
    if not train_run_id:
        return {}
    try:
        same = client.get_run(train_run_id).info.experiment_id == exp_id
    except Exception:  # a training run this store does not hold (evaluated from a copied folder)
        return {}
    return {"mlflow.parentRunId": train_run_id} if same else {}


@contextmanager
def _ended(client, rid: str) -> Iterator[None]:
    """The run ends FINISHED after the block; KILLED if it was interrupted (Ctrl-C, SIGTERM),
    FAILED if it failed (ending it never hides the error)."""
    try:
        yield
        client.set_terminated(rid, "FINISHED")
    except BaseException as e:
        try:
            client.set_terminated(rid, end_status(e))
        except Exception:
            pass
        raise


def load_evaluation_rows(client, experiment: str, protocol: str | None = None,
                         notes: list[str] | None = None) -> pd.DataFrame:
    """All per-simulation rows of the experiment's finished evaluation runs; with `protocol`
    (the report's own, `eval_key.protocol_key`), those of the study's protocol only: `protocol`
    where runs hold it, else the one most runs hold (the earliest first among equals: a study's
    evaluations precede one-offs). A one-off evaluation of the same run never replaces the
    study's; the seeds evaluated under other protocols alone are named in `notes`."""
    # lazy: MLflow (~1 s) and pandas only where a store or rows are used
    import pandas as pd

    exp_id = experiment_id(client, experiment)
    if exp_id is None:
        raise SigmarlError(f"no MLflow experiment named {experiment!r} (set tracking.experiment=...)")
    runs = client.search_runs(
        [exp_id], filter_string="tags.kind = 'evaluation' and attributes.status = 'FINISHED'",
        order_by=["attributes.start_time ASC"],
    )
    frames = []
    # Keep the newest evaluation of each (model, seed, training config) so a re-evaluation
    # replaces the old one, and a run of another config under the same label does not hide the
    # declared one's (the report chooses by fingerprint: sigmarl.results.columns)
    latest, others = {}, {}
    protocol = _study_protocol(runs, protocol) if protocol is not None else None
    for run in runs:
        tags = run.data.tags
        key = (tags.get("model"), tags.get("seed"), tags.get("obs"), tags.get("fingerprint", ""))
        theirs = _protocol_of(run)
        if protocol is not None and theirs is not None and theirs != protocol:
            others[key] = theirs
            continue
        latest.pop(key, None)
        latest[key] = run  # re-inserted: the dict's order is the evaluations' order
    lacking = [f"{key[0]} seed {key[1]} evaluated under another protocol ({theirs}) only, not the study's "
               f"({protocol}): left out; `sigmarl sweep` evaluates it under the study's"
               for key, theirs in others.items() if key not in latest]
    if notes is not None:
        notes.extend(lacking)
    with tempfile.TemporaryDirectory() as tmp:
        for run in latest.values():
            path = client.download_artifacts(run.info.run_id, ROWS_ARTIFACT, tmp)
            frame = pd.read_csv(path)
            frame["eval_run_id"] = run.info.run_id
            frame["fingerprint"] = run.data.tags.get("fingerprint", "")
            frames.append(frame)
    if not frames:
        raise SigmarlError(
            f"no finished evaluation runs in experiment {experiment!r}: run `sigmarl sweep` "
            "or `sigmarl evaluate <run>` first" + "".join(f"; {line}" for line in lacking)
        )
    return pd.concat(frames, ignore_index=True)


def _protocol_of(run) -> str | None:
    """An evaluation run's protocol: its tag, or its evaluation key (equal, for runs before the tag)."""
    return run.data.tags.get("protocol_key", run.data.tags.get("eval_key"))


def _study_protocol(runs, preferred: str) -> str:
    held = Counter(p for run in runs if (p := _protocol_of(run)) is not None)
    return preferred if preferred in held or not held else held.most_common(1)[0][0]


def evaluated_config(client, eval_run_id: str):
    """The training config of the run an evaluation run evaluated (its checkpoint's run
    folder's config.yaml), None where that folder is not on this machine."""
    checkpoint = client.get_run(eval_run_id).data.tags.get("checkpoint")
    path = Run(Path(checkpoint).parent).config_file if checkpoint else None
    return read_run_config(path) if path is not None and path.is_file() else None


def _last_per_step(client, run_id: str, metric: str) -> dict[int, float]:
    history = sorted(client.get_metric_history(run_id, metric), key=lambda m: m.timestamp)
    return {m.step: m.value for m in history}


def load_training_curves(client, experiment: str, metric: str = REWARD_COLUMN) -> pd.DataFrame:
    """(model, seed, iteration, reward, seconds) for the experiment's training runs; seconds:
    the iteration's compute time (NaN where the run logged no timings)."""
    # lazy: MLflow (~1 s) and pandas only where a store or rows are used
    import pandas as pd

    columns = ["model", "seed", "iteration", "reward", "seconds"]
    exp_id = experiment_id(client, experiment)
    if exp_id is None:
        return pd.DataFrame(columns=columns)
    runs = client.search_runs([exp_id], filter_string="tags.kind = 'training'")
    frames = []
    for run in runs:
        # a resumed run may log a step twice: the last value counts, as in a folder's metrics.csv
        reward = _last_per_step(client, run.info.run_id, metric)
        seconds: Counter[int] = Counter()  # update() adds: an iteration's timings summed
        for name in TIMINGS:
            seconds.update(_last_per_step(client, run.info.run_id, name))
        steps = sorted(reward)
        frames.append(pd.DataFrame({"model": run.data.tags.get("model"), "seed": run.data.tags.get("seed"),
                                    "iteration": steps, "reward": [reward[s] for s in steps],
                                    "seconds": [seconds.get(s, float("nan")) for s in steps]}))
    return pd.concat(frames, ignore_index=True)[columns] if frames else pd.DataFrame(columns=columns)


def evaluated_checkpoint(client, experiment: str, model: str) -> Path | None:
    """The checkpoint file of the model's first-seed evaluation, if it is on this machine."""
    exp_id = experiment_id(client, experiment)
    if exp_id is None:
        return None
    runs = client.search_runs([exp_id], filter_string=f"tags.kind = 'evaluation' and tags.model = '{model}'",
                              order_by=["tags.seed ASC"], max_results=1)
    path = Path(runs[0].data.tags.get("checkpoint", "")) if runs else None
    return path if path is not None and path.is_file() else None


def training_checkpoint(client, run_id: str, name: str, download_dir: Path) -> Path:
    """Checkpoint `name` of a training run: in its run folder if that is on this machine,
    else downloaded from the run's artifacts."""
    try:
        run = client.get_run(run_id)
    except Exception as e:
        raise SigmarlError(f"{run_id!r} is neither a checkpoint file, a run folder nor an MLflow run id") from e
    local = Path(run.data.params.get("run_dir", "")) / name
    if local.is_file():
        return local
    try:
        return Path(client.download_artifacts(run_id, name, str(download_dir)))
    except Exception as e:
        raise SigmarlError(f"MLflow run {run_id} has no {name} artifact") from e


def log_report(client, experiment: str, composite: pd.DataFrame, paths: Iterable[Path],
               tags: dict[str, str], source: str | None = None) -> str:
    """A report run: the table files, figures and composite scores, with what it was built from;
    named after what it reports (`report <experiment>`, or `report <results folder>`)."""
    from mlflow.entities import Param

    exp_id = experiment_id(client, experiment, create=True)
    end_dead_reports(client, exp_id)
    owner = {OWNER_HOST: socket.gethostname(), OWNER_PID: str(os.getpid())}
    run = client.create_run(exp_id, run_name=report_name(source or experiment, tags),
                            tags={"kind": "report", **owner, **tags})
    rid = run.info.run_id
    with _ended(client, rid):
        # what tells report runs apart, as params too: the runs table can show and compare them
        client.log_batch(rid, params=[Param(k, tags[k][:6000]) for k in REPORT_PARAMS if tags.get(k)])
        for _, r in composite.dropna(subset=[CS]).iterrows():
            client.log_metric(rid, f"{CS}/{r['scenario']}/{r['model']}", round(float(r[CS]), TABLE_DIGITS))
        crash.point("report:logging")
        for path in paths:
            client.log_artifact(rid, str(path))
    return rid


REPORT_PARAMS = ("baseline", "models", "scenarios", "metrics", "overrides")


def report_name(where: str, tags: dict[str, str]) -> str:
    """`report <experiment>: M0 vs M1,M4 on CPM,Roundabout` (at most 200 characters)."""
    base, models = tags.get("baseline", ""), [m for m in tags.get("models", "").split(",") if m]
    scenarios = [s for s in tags.get("scenarios", "").split(",") if s]
    if not base or not models:
        return f"report {where}"
    others = [m for m in models if m != base]
    what = f"{base} vs {','.join(others)}" if others else f"{base} alone"
    on = ",".join(scenarios) if len(scenarios) <= 4 else f"{len(scenarios)} scenarios"
    name = f"report {where}: {what} on {on}"
    return name if len(name) <= 200 else name[:197] + "..."


def end_dead_reports(client, exp_id: str) -> list[str]:
    """End KILLED the report runs left RUNNING by a process that no longer lives (`kill -9`,
    a power cut: no handler ran to end them). A run names its process by host and pid; only
    runs of this host can be checked, and a pid reused since keeps its run RUNNING until that
    process ends too (never a live report ended)."""
    host = socket.gethostname()
    ended = []
    for run in client.search_runs([exp_id], filter_string="tags.kind = 'report' and attributes.status = 'RUNNING'"):
        tags = run.data.tags
        if tags.get(OWNER_HOST) != host or not tags.get(OWNER_PID, "").isdigit():
            continue
        if not _alive(int(tags[OWNER_PID])):
            client.set_terminated(run.info.run_id, "KILLED")
            ended.append(run.info.run_id)
    return ended


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)  # signal 0: only whether the process exists
    except ProcessLookupError:
        return False
    except PermissionError:  # exists, another user's
        return True
    return True
