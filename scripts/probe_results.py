"""Probes of issue 59's round: results stay the study's (a one-off evaluation, a seed of other
settings), sigmarl writes only into what is its own, `report --from` holds rows to their SHA-256,
a re-run records one run per folder, a killed report's staging folder does not outlive it, and
the exit codes docs/reference/cli.md promises."""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

import probe_fixtures as fx
from probe_kit import SMOKE, TINY_EVAL, Probe, files, last_line, refusal, sigmarl

REPORT = ["report", "study=quick", fx.STORE, "--no-figures", "--out", "report"]
FROM = ["report", "--from", "results", "--no-figures", "--out", "out", "tracking.enabled=false"]


def _one_off(folder: Path) -> str | None:
    """N1: `evaluate --scenario` of another scenario must not move the study's table."""
    fx.copy_of(fx.study)(folder)
    rows = (folder / fx.RUN / "evaluation_rows.csv").read_bytes()
    done = sigmarl(REPORT, folder)
    if done.returncode != 0:
        return f"the study's report failed (rc {done.returncode}): {last_line(done)}"
    before = (folder / "report" / "table.csv").read_text()
    done = sigmarl(["evaluate", str(fx.RUN), "--scenario", "CPM", fx.STORE, "eval.n_sims=1", "eval.steps=5"], folder)
    if done.returncode != 0:
        return f"the one-off evaluation failed (rc {done.returncode}): {last_line(done)}"
    if (folder / fx.RUN / "evaluation_rows.csv").read_bytes() != rows:
        return "the one-off evaluation rewrote the study's evaluation_rows.csv"
    done = sigmarl(REPORT, folder)
    if done.returncode != 0:
        return f"the report after it failed (rc {done.returncode}): {last_line(done)}"
    after = (folder / "report" / "table.csv").read_text()
    return None if after == before else "the one-off evaluation changed the study's table.csv"


def _users_folder(folder: Path) -> None:
    (folder / "mywork").mkdir()
    (folder / "mywork" / "config.yaml").write_text("my: notes\n")
    (folder / "mywork" / "metrics.csv").write_text("day,hours\nmonday,3\n")


def _edited_rows(folder: Path) -> None:
    """H3: a results folder whose notes record their rows' SHA-256, one rows file then edited
    to other valid values (one simulation's CD doubled)."""
    import pandas as pd

    root = fx.results_copy(folder)
    paths = sorted(root.glob("*/seed*/evaluation_rows.csv"))
    for path in paths:
        digest = hashlib.sha256(path.read_bytes()).hexdigest()
        (path.parent / "evaluation.json").write_text(json.dumps({"eval_key": "k", "rules": 2, "rows_sha256": digest}))
    rows = pd.read_csv(paths[0])
    rows.loc[0, "CD"] = rows.loc[0, "CD"] * 2 + 1
    rows.to_csv(paths[0], index=False)


def _study_seed0(folder: Path) -> None:
    """N2: the quick study's M0 seed 0 as its sweep leaves its config.yaml (nothing trained)."""
    from omegaconf import OmegaConf

    from sigmarl.compose import compose_config
    from sigmarl.config import as_dict

    cfg = compose_config(["study=quick", "obs=full", "model=M0", "ppo=smoke", "runs_root=runs", "seed=0"])
    (folder / fx.RUN).mkdir(parents=True)
    (folder / fx.RUN / "config.yaml").write_text(OmegaConf.to_yaml(as_dict(cfg)))


def _rerun_records(folder: Path) -> str | None:
    """H4: a finished folder re-run twice against a store that lacks its run: one training run."""
    fx.copy_of(fx.whole)(folder)
    rerun = ["train", "ppo=smoke", "threads=1", f"ppo.iterations={fx.ITERATIONS}", "ppo.checkpoint_every=1",
             "runs_root=runs", "resume=true", fx.STORE]
    for attempt in (1, 2):
        done = sigmarl(rerun, folder)
        if done.returncode != 0:
            return f"re-run {attempt} failed (rc {done.returncode}): {last_line(done)}"
    from mlflow.tracking import MlflowClient

    client = MlflowClient(f"sqlite:///{folder / 'mlflow.db'}")
    runs = [r for e in client.search_experiments()
            for r in client.search_runs([e.experiment_id], "tags.kind = 'training'")]
    return None if len(runs) == 1 else f"{len(runs)} training runs recorded for one folder, not 1"


def _stale_staging(folder: Path) -> str | None:
    """Item 7: a staging folder a report killed by SIGKILL left is removed by the next report."""
    fx.results_copy(folder)
    (folder / "out" / ".staging-k2j4x9ab" / "figures").mkdir(parents=True)
    done = sigmarl(FROM, folder)
    if done.returncode != 0:
        return f"the report failed (rc {done.returncode}): {last_line(done)}"
    left = sorted(p.name for p in (folder / "out").glob(".staging-*"))
    return None if not left else f"the report left {left} in its folder"


def _root_unchanged(folder: Path) -> str | None:
    """H1: `run_dir=/` refused, and / left as it was (names of its entries)."""
    before = sorted(p.name for p in Path("/").iterdir())
    wrong = refusal(["train", *SMOKE, "run_dir=/"], "not a sigmarl run folder")(folder)
    after = sorted(p.name for p in Path("/").iterdir())
    return wrong or (None if after == before else f"/ gained {sorted(set(after) - set(before))}")


def _missing_checkpoint(folder: Path) -> str | None:
    return refusal(["evaluate", "runs/M0/seed9/best.pt", "tracking.enabled=false"], "checkpoint not found")(folder)


def _users_folder_kept(folder: Path) -> str | None:
    wrong = refusal(["train", *SMOKE, "run_dir=mywork"], "not a sigmarl run folder", _users_folder)(folder)
    if wrong is None and set(files(folder)) != {Path("mywork/config.yaml"), Path("mywork/metrics.csv")}:
        return f"files other than the user's: {sorted(map(str, files(folder)))}"
    shutil.rmtree(folder / "runs", ignore_errors=True)
    return wrong


PROBES = [
    Probe("N1-one-off", "an evaluation of another scenario of a study's seed, then the study's report", _one_off,
          trains=True),
    Probe("H1-users-folder", "run_dir= naming a user's folder with a config.yaml of theirs", _users_folder_kept),
    # out of --quick (the suite's): were the refusal ever lost, the suite run as root would write into /
    Probe("H1-root", "run_dir=/", _root_unchanged, trains=True),
    Probe("H3-edited-rows", "report --from with a rows file edited to other valid values",
          refusal(FROM, "differs from the SHA-256", _edited_rows)),
    Probe("N2-other-settings", "a sweep adding a seed of other settings beside a study's seeds",
          refusal(["sweep", "study=quick", "models=[M0]", *SMOKE, *TINY_EVAL, "seeds=[3]", "ppo.iterations=5",
                   "runs_root=runs"], "trained with other settings", _study_seed0)),
    Probe("N2-other-config", "a sweep over a run folder of another training config (docs/reference/cli.md)",
          refusal(["sweep", "study=quick", "models=[M0]", *SMOKE, *TINY_EVAL, "seeds=[0]", "ppo.iterations=5",
                   "runs_root=runs"], "holds a run of another training config", _study_seed0)),
    Probe("H4-rerun-records", "a finished folder re-run twice against a store that lacks its run", _rerun_records,
          trains=True),
    Probe("report-staging", "a staging folder a killed report left, then a report into the same folder",
          _stale_staging),
    Probe("exit-missing-checkpoint", "evaluate a checkpoint that does not exist (docs/reference/cli.md)",
          _missing_checkpoint),
]
