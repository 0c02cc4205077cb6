"""Evaluate a trained model (checkpoint file, run folder or MLflow run id) on the study's scenarios.

The order makes a failure cheap: the tracking store is checked first, the rows are written
to a file (`evaluation_rows.csv` beside the checkpoint) before they are logged, and a re-run
whose file matches the protocol and the checkpoint logs that file instead of evaluating again.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import pandas as pd

from sigmarl import crash
from sigmarl.ablation import obs_strategies
from sigmarl.compose.validate import check_eval
from sigmarl.config import Config, EvalConfig, as_dict
from sigmarl.env.paper_rules import rules_label
from sigmarl.errors import SigmarlError
from sigmarl.eval_key import RULES_REVISION, eval_key, protocol, protocol_key
from sigmarl.evaluation.rollout import evaluate_policy
from sigmarl.evaluation.target import checkpoint_name, resolve_checkpoint  # noqa: F401 (their old home)
from sigmarl.identity import fingerprint
from sigmarl.metrics import MEASURED, measured
from sigmarl.paths import ensure_writable
from sigmarl.policy_input import check_evaluable
from sigmarl.rows import note_protocol, rows_measured
from sigmarl.run import ROWS_FILE, ROWS_META, Run, write_atomic
from sigmarl.scenarios import scenario as scenario_of
from sigmarl.tracking import Tracker, open_tracker
from sigmarl.training import checkpoint as ckpt
from sigmarl.training.loop import load_policy


def evaluate_checkpoint(path: Path, eval_cfg: EvalConfig, scenarios: list[str] | None = None,
                        device: str = "cpu", progress: bool = True) -> tuple[pd.DataFrame, dict]:
    """Per-simulation rows of a trained policy on each scenario, and the checkpoint's state."""
    scenarios = check_eval(eval_cfg, scenarios or None)
    saved = ckpt.load(path, device)  # the policy's input size, checked before any scenario is built
    check_evaluable(ckpt.config_of(saved, path).obs, saved["dims"]["obs_dim"], scenarios, f"checkpoint {path}")
    frames = []
    state = None
    for scenario in scenarios:
        n_agents = scenario_of(scenario).n_agents
        actor, state = load_policy(path, n_agents=n_agents, device=device)
        train_cfg = ckpt.config_of(state, path)
        rows = evaluate_policy(actor, train_cfg, scenario, n_sims=eval_cfg.n_sims, steps=eval_cfg.steps,
                               seed=eval_cfg.seed, n_agents=n_agents, device=device, progress=progress)
        frames.append(rows)
        crash.point(f"eval:scenario:{scenario}")
    rows = pd.concat(frames, ignore_index=True)
    rows.insert(0, "model", train_cfg.model)  # the run's label (the study's variant)
    rows.insert(1, "obs", obs_strategies(train_cfg.obs))
    rows.insert(2, "seed", int(train_cfg.seed))
    # the rules the policy was trained and evaluated under (the metrics are always ours)
    rows.insert(3, "rules", rules_label(train_cfg.rules))
    # which study and training config the rows belong to (rows from before have neither)
    rows["study"] = train_cfg.study.name
    rows["fingerprint"] = fingerprint(train_cfg)
    return rows, state


def rows_rules(rows: pd.DataFrame) -> pd.Series:
    """The rules each evaluation row's policy ran under (`ours`, `paper` or the switches on):
    rows written before the `rules` column existed were all measured under ours."""
    if "rules" not in rows.columns:
        return pd.Series("ours", index=rows.index, name="rules")
    return rows["rules"].fillna("ours")


def rows_file_for(checkpoint: Path, cfg: Config) -> Path:
    """Where `sigmarl evaluate` keeps the rows: evaluation_rows.csv beside the checkpoint when
    they are its study's protocol (`eval_key.protocol`), else evaluation_rows-<protocol key>.csv
    beside it. A one-off evaluation (another scenario set, fewer simulations, other steps) never
    replaces the study's rows, which its report and sweep read."""
    key = protocol_key(cfg.eval)
    default = Run(checkpoint.parent).rows_file
    study = study_protocol(checkpoint.parent)
    return default if study in (None, key) else checkpoint.parent / f"evaluation_rows-{key}.csv"


def study_protocol(run_dir: Path) -> str | None:
    """The protocol key of the run folder's study: that of its evaluation_rows.csv where a note
    says it, else that of the evaluation its config.yaml was trained for; None where neither is
    known (a checkpoint outside a run folder)."""
    meta = _read_meta(Run(run_dir).rows_file)
    if meta is not None and isinstance(found := note_protocol(meta), str):
        return found
    config = Run(run_dir).config_file
    if not config.is_file():
        return None
    from sigmarl.readers import read_run_config

    try:
        return protocol_key(read_run_config(config).eval)
    except SigmarlError:
        return None


def _meta_path(rows_file: Path) -> Path:
    return rows_file.with_name(ROWS_META if rows_file.name == ROWS_FILE else rows_file.stem + ".json")


def _read_meta(rows_file: Path) -> dict | None:
    """The rows' note, or None where there is none (or none readable: the rows are measured again)."""
    try:
        meta = json.loads(_meta_path(rows_file).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return meta if isinstance(meta, dict) else None


def _identity(path: Path, cfg: Config) -> dict[str, str]:
    return {"eval_key": eval_key(cfg.eval),
            "checkpoint_sha256": file_sha256(path)}


def file_sha256(path: Path) -> str:
    """The file's SHA-256, read in blocks: a checkpoint may be larger than the memory to spare."""
    with path.open("rb") as f:
        return hashlib.file_digest(f, "sha256").hexdigest()


def saved_rows(rows_file: Path, identity: dict[str, str]) -> pd.DataFrame | None:
    meta = _read_meta(rows_file)
    if meta is None or {k: meta.get(k) for k in identity} != identity \
            or not rows_measured(rows_file, _meta_path(rows_file), identity["eval_key"]):
        return None  # none saved, another protocol's or checkpoint's, or damaged: evaluate again
    # the columns' own types (float32 metrics) make the values read back exactly those written
    exact = {} if int(pd.__version__.split(".")[0]) >= 3 else {"float_precision": "round_trip"}
    try:
        return pd.read_csv(rows_file, dtype=meta.get("dtypes"), **exact)
    except (ValueError, TypeError):  # a note's dtypes damaged: measure the rows again
        return None


def save_rows(rows: pd.DataFrame, rows_file: Path, identity: dict[str, str], eval_cfg: EvalConfig) -> None:
    """Rows first, then the note saying what they are: a kill in between leaves no note."""
    _meta_path(rows_file).unlink(missing_ok=True)
    text = rows.to_csv(index=False)
    write_atomic(rows_file, text)
    # `rows_sha256`: a cut or edited rows file is evaluated again, not reused or counted finished
    # `rules`: which environment rules measured them (`report --from` leaves out older ones)
    meta = {**identity, "rows_sha256": hashlib.sha256(text.encode("utf-8")).hexdigest(), "rules": RULES_REVISION,
            "dtypes": {c: str(t) for c, t in rows.dtypes.items()}}
    # the protocol, its key and in words: what tells a one-off evaluation from the study's
    meta.update(protocol_key=protocol_key(eval_cfg), protocol=protocol(eval_cfg))
    # `rules_label`: the policy's rules switches (`ours`, `paper` or those on; old rows: ours)
    meta["rules_label"] = str(rows["rules"].iloc[0]) if "rules" in rows.columns and len(rows) else "ours"
    write_atomic(_meta_path(rows_file), json.dumps(meta, indent=1) + "\n")


def evaluate_rows(path: Path, cfg: Config, rows_file: Path | None, scenarios=None,
                  progress: bool = True, add_metrics: bool = False) -> tuple[pd.DataFrame, dict]:
    """The checkpoint's evaluation rows and the checkpoint: those saved in `rows_file` under the
    same protocol and checkpoint, or evaluated now (and saved there). With `add_metrics`, saved
    rows that lack a metric declared since are completed (`completed_rows`)."""
    from sigmarl.training import checkpoint as ckpt

    identity = _identity(path, cfg) if rows_file is not None else {}
    rows = saved_rows(rows_file, identity) if rows_file is not None else None
    if rows is not None and add_metrics and [m for m in MEASURED if m not in rows.columns]:
        rows = completed_rows(rows_file, identity, evaluate_checkpoint(path, cfg.eval, scenarios, cfg.device,
                                                                        progress)[0], cfg.eval)
    if rows is not None:
        return rows, ckpt.load(path, cfg.device)
    if rows_file is not None:
        ensure_writable(rows_file.parent, "cannot write the evaluation rows there; use --out <file>")
    rows, state = evaluate_checkpoint(path, cfg.eval, scenarios, device=cfg.device, progress=progress)
    if rows_file is not None:
        save_rows(rows, rows_file, identity, cfg.eval)
    return rows, state


def completed_rows(rows_file: Path, identity: dict[str, str], fresh: pd.DataFrame, eval_cfg: EvalConfig) -> pd.DataFrame:
    """The saved rows with the metric columns they lack taken from `fresh` (the same checkpoint
    evaluated again under the same protocol), every saved column's text kept as it was. Refused
    where the fresh rollout does not reproduce the saved metrics: the added ones would describe
    another rollout."""
    import numpy as np

    text = pd.read_csv(rows_file, dtype=str, keep_default_na=False)
    saved = saved_rows(rows_file, identity)
    keys = ["scenario", "simulation"]
    fresh = saved[keys].merge(fresh, on=keys, how="left", suffixes=("_saved", ""))
    for name in measured(saved):
        if not np.allclose(saved[name].astype(float), fresh[name].astype(float), rtol=1e-4, atol=1e-6):
            raise SigmarlError(f"{rows_file}: evaluated again, {name} differs from the saved rows (another "
                               "device or version?); the metrics cannot be added to them. Evaluate the run "
                               "anew instead (delete evaluation_rows.csv and evaluate again)")
    added = [m for m in MEASURED if m not in saved.columns]
    for name in added:
        text[name] = fresh[name].to_numpy()
    meta = _read_meta(rows_file) or {}
    save_rows(text, rows_file, identity, eval_cfg)
    dtypes = {**meta.get("dtypes", {}), **{m: str(fresh[m].dtype) for m in added}}
    note = json.loads(_meta_path(rows_file).read_text(encoding="utf-8"))
    note.update(dtypes=dtypes, added_metrics=added)
    write_atomic(_meta_path(rows_file), json.dumps(note, indent=1) + "\n")
    return saved_rows(rows_file, identity)


def has_rows(rows_file: Path, cfg: Config) -> bool:
    """Whether `rows_file` holds whole rows measured under `cfg`'s evaluation protocol."""
    return rows_measured(rows_file, _meta_path(rows_file), eval_key(cfg.eval))


def evaluate_and_log(path: Path, cfg: Config, train_run_id: str | None, scenarios=None,
                     progress: bool = True, rows_file: Path | None = None,
                     tracker: Tracker | None = None, add_metrics: bool = False) -> tuple[pd.DataFrame, str | None]:
    """Evaluate a checkpoint and record it as an evaluation run in `tracker` (default: the one
    `cfg` chooses; none with tracking off).

    The store is checked before evaluating; with `rows_file`, the rows are saved there
    before logging, and rows saved by an earlier attempt under the same protocol and
    checkpoint are logged without evaluating again.
    """
    tracker = tracker or open_tracker(cfg)  # the store is checked before evaluating
    rows, state = evaluate_rows(path, cfg, rows_file, scenarios, progress, add_metrics)
    crash.point("eval:rows")
    train_cfg = ckpt.config_of(state, path)
    tags = {
        "model": str(rows["model"].iloc[0]),
        "obs": obs_strategies(train_cfg.obs),
        "study": train_cfg.study.name,
        "fingerprint": fingerprint(train_cfg),
        "seed": str(train_cfg.seed),
        "train_run_id": train_run_id or state.get("mlflow_run_id") or "",
        "checkpoint": str(path),
        "eval_key": eval_key(cfg.eval),
        "protocol_key": protocol_key(cfg.eval),  # a report reads its study's protocol only
    }
    params = {f"eval.{k}": str(v) for k, v in as_dict(cfg.eval).items()}
    params["checkpoint_iteration"] = str(state.get("iteration"))
    # what the UI groups and compares evaluations by: the variant, what makes it, what trained
    params.update({"variant": tags["model"], "overrides": " ".join(train_cfg.overrides)[:6000],
                   "fingerprint": tags["fingerprint"], "obs": tags["obs"], "seed": tags["seed"]})
    run_id = tracker.log_evaluation(rows, tags, params)
    return rows, run_id
