"""The study in MLflow: its experiment opens on its runs (MLflow 3's experiment kind) with a
description naming the study, its variants and its baseline, and one study run per study holds
its training runs as children (each evaluation is a child of its training), so that the runs
page reads study -> variant and seed -> evaluation."""

from __future__ import annotations

import json
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
VARIANTS_TAG = "sigmarl.variants"  # JSON {label: overrides} of every variant the study's sweeps ran


def description(study: StudyConfig, variants: dict[str, list[str]] | None = None) -> str:
    """The experiment's description (Markdown): the study, its variants (`variants`: those its
    sweeps have run, the declared ones included) and its baseline."""
    variants = dict(study.variants) if variants is None else variants
    lines = [f"**Study {study.name}**: {len(variants)} variant(s), baseline **{study.baseline}**, "
             f"declared seeds {list(study.seeds)}, scenarios {', '.join(study.scenarios)}.", ""]
    lines += [f"- {label}: `{' '.join(overrides) or '(the config as composed)'}`"
              + (f" (against {study.baselines[label]})" if label in study.baselines else "")
              + ("" if label in study.variants else " (added by a command-line sweep)")
              for label, overrides in variants.items()]
    return "\n".join(lines)


def _recorded(run) -> dict[str, list[str]]:
    """The variants an earlier sweep recorded on the study run (its tag VARIANTS_TAG)."""
    try:
        found = json.loads(run.data.tags.get(VARIANTS_TAG, "{}")) if run is not None else {}
    except ValueError:  # an edited tag: the declared variants still describe the study
        return {}
    return {str(k): [str(o) for o in v] for k, v in found.items() if isinstance(v, list)} \
        if isinstance(found, dict) else {}


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


def open_study_run(client, experiment: str, study: StudyConfig, added: dict[str, list[str]] | None = None) -> str:
    """The study run of `study` (created the first time), RUNNING while its sweep runs; the
    experiment described with every variant its sweeps ran (`added`: this sweep's own, beyond
    the declared ones), so a description never says 6 variants after 2 more were run."""
    exp_id = experiment_id(client, experiment, create=True)
    run = find(client, exp_id, study.name)
    variants = {**_recorded(run), **dict(study.variants), **(added or {})}
    describe(client, exp_id, study)
    client.set_experiment_tag(exp_id, NOTE_TAG, description(study, variants))
    tags = {"kind": "study", "study": study.name, "variants": ", ".join(variants),
            "baseline": study.baseline, NOTE_TAG: description(study, variants),
            VARIANTS_TAG: json.dumps(variants)[:5000]}
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
def study_run(client, cfg: Config, added: dict[str, list[str]] | None = None) -> Iterator[str | None]:
    """The sweep's study run around its jobs: FINISHED after them, KILLED or FAILED if the sweep
    itself ends so. A store that refuses it costs a warning: the run folders are the record, the
    study run only arranges the view."""
    try:
        rid = open_study_run(client, cfg.tracking.experiment, cfg.study, added)
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
