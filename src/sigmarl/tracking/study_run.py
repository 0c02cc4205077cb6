"""The study in MLflow: its experiment opens on its runs (MLflow 3's experiment kind) with a
description naming the study, its variants and its baseline, and one study run per study holds
its training runs as children (each evaluation is a child of its training), so that the runs
page reads study -> variant and seed -> evaluation."""

from __future__ import annotations

import sys
from collections.abc import Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING

from sigmarl.errors import end_status
from sigmarl.tracking.meta import git_commit
from sigmarl.tracking.store import KIND, KIND_TAG, experiment_id

if TYPE_CHECKING:
    from sigmarl.config import Config, StudyConfig

NOTE_TAG = "mlflow.note.content"  # the description the UI shows above the runs
PARENT_TAG = "mlflow.parentRunId"


def description(study: StudyConfig) -> str:
    """The experiment's description (Markdown): the study, its variants and its baseline."""
    lines = [f"**Study {study.name}**: {len(study.variants)} variant(s), baseline **{study.baseline}**, "
             f"declared seeds {list(study.seeds)}, scenarios {', '.join(study.scenarios)}.", ""]
    lines += [f"- {label}: `{' '.join(overrides) or '(the config as composed)'}`"
              + (f" (against {study.baselines[label]})" if label in study.baselines else "")
              for label, overrides in study.variants.items()]
    return "\n".join(lines)


def describe(client, exp_id: str, study: StudyConfig | None) -> None:
    """Set the experiment's kind, and its description where a study is given."""
    client.set_experiment_tag(exp_id, KIND_TAG, KIND)
    if study is not None:
        client.set_experiment_tag(exp_id, NOTE_TAG, description(study))


def find(client, exp_id: str, study: str):
    """The study run of `study` in the experiment (the newest, if a race made two), or None."""
    runs = client.search_runs([exp_id], filter_string=f"tags.kind = 'study' and tags.study = '{study}'",
                              order_by=["attributes.start_time DESC"], max_results=1)
    return runs[0] if runs else None


def open_study_run(client, experiment: str, study: StudyConfig) -> str:
    """The study run of `study` (created the first time), RUNNING while its sweep runs; the
    experiment described."""
    exp_id = experiment_id(client, experiment, create=True)
    describe(client, exp_id, study)
    run = find(client, exp_id, study.name)
    tags = {"kind": "study", "study": study.name, "variants": ", ".join(study.variants),
            "baseline": study.baseline, "mlflow.note.content": description(study)}
    if commit := git_commit():
        tags["git_commit"] = commit
    if run is None:
        return client.create_run(exp_id, run_name=f"study {study.name}", tags=tags).info.run_id
    for key, value in tags.items():
        client.set_tag(run.info.run_id, key, value)
    client.update_run(run.info.run_id, status="RUNNING")
    return run.info.run_id


def parent_of(client, exp_id: str, study: str) -> dict[str, str]:
    """The tag that nests a training run of `study` under its study run, if there is one."""
    run = find(client, exp_id, study)
    return {PARENT_TAG: run.info.run_id} if run is not None else {}


@contextmanager
def study_run(client, cfg: Config) -> Iterator[str | None]:
    """The sweep's study run around its jobs: FINISHED after them, KILLED or FAILED if the sweep
    itself ends so. A store that refuses it costs a warning: the run folders are the record, the
    study run only arranges the view."""
    try:
        rid = open_study_run(client, cfg.tracking.experiment, cfg.study)
    except Exception as e:  # noqa: BLE001 - the sweep goes on without its study run
        print(f"sigmarl: warning: MLflow study run not recorded ({(str(e).splitlines() or [repr(e)])[0]})",
              file=sys.stderr)
        yield None
        return
    status = "FINISHED"
    try:
        yield rid
    except BaseException as e:
        status = end_status(e)
        raise
    finally:
        try:
            client.set_terminated(rid, status)
        except Exception:  # noqa: BLE001 - never hides the sweep's own end
            pass
