"""A results folder read from disk (no MLflow): its run folders, `<root>/<label>/seed<k>/` as a
sweep writes them (`runs_root=...`; their files in docs/reference/outputs.md), their evaluation
rows and training curves, and the rows of the paper's own policies.

A run folder without evaluation rows (training unfinished) is left out and named in the notes;
without metrics.csv it has no training curve. The paper's policies' rows (`sigmarl evaluate
paper:M<k>`, in `paper-policies/<label>/<rules>/` beside the study's folder) are read for the
`paper_policies` section only, never pooled with a study's rows.
"""

from __future__ import annotations

import hashlib
import json
import re
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd

from sigmarl.ablation import MODELS, TIMINGS
from sigmarl.errors import SigmarlError
from sigmarl.eval_key import RULES_REVISION
from sigmarl.params import VEHICLE
from sigmarl.readers import read_run_config, read_training_curve
from sigmarl.results.columns import run_state
from sigmarl.rows import check_rows, note_protocol
from sigmarl.run import COMPLETE_REWARD_COLUMN, REWARD_COLUMN, ROWS_FILE, Run

_SEED_DIR = re.compile(r"seed(-?\d+)")
IMPORTED_FOLDER = "paper-policies"  # beside a results folder: the paper's own policies' rows
# the paper's speed command range: under its drag dynamics a speed may pass ours (0.8) in a transient
PAPER_TOP_SPEED = 1.0


@dataclass(frozen=True)
class RunFolder:
    label: str  # the model folder's name
    seed: int
    path: Path


@dataclass
class FolderResults:
    rows: pd.DataFrame
    curves: pd.DataFrame  # model, seed, iteration, reward, seconds
    runs: list[RunFolder]
    notes: list[str] = field(default_factory=list)


def run_folders(root: Path) -> list[RunFolder]:
    """Every <label>/seed<k>/ folder under `root`, models M0..M5 first, then by name and seed."""
    root = Path(root)
    if not root.is_dir():
        raise SigmarlError(f"results folder not found: {root}")
    found = [RunFolder(model_dir.name, int(m.group(1)), seed_dir)
             for model_dir in root.iterdir() if model_dir.is_dir()
             for seed_dir in model_dir.iterdir() if (m := _SEED_DIR.fullmatch(seed_dir.name)) and seed_dir.is_dir()]
    order = {name: i for i, name in enumerate(MODELS)}
    found.sort(key=lambda r: (order.get(r.label, len(order)), r.label, r.seed))
    if not found:
        raise SigmarlError(f"{root} holds no run folders (expected <model>/seed<k>/ inside it)")
    return found


def _read_csv(path: Path) -> pd.DataFrame:
    try:
        return pd.read_csv(path, float_precision="round_trip")
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as e:
        raise SigmarlError(f"{path} is not a readable CSV: {str(e).splitlines()[0]}") from e


def rows_of(run: RunFolder) -> pd.DataFrame:
    """The run's evaluation rows, checked (`check_rows`), and its model and seed checked
    against the folder's names."""
    path = Run(run.path).rows_file
    rows = check_rows(_read_csv(path), path, _top_speed(run))
    if "seed" not in rows.columns:
        rows.insert(0, "seed", run.seed)
    if "model" not in rows.columns:
        rows.insert(0, "model", run.label)
    models = set(rows["model"].astype(str))
    # a folder named by its label holds that label's rows (folders of older sweeps were named
    # by observation preset, so those are taken as they are)
    if run.label not in MODELS.values() and models != {run.label}:
        raise SigmarlError(f"{path} holds rows of model {', '.join(sorted(models))}, not {run.label}")
    seeds = set(pd.to_numeric(rows["seed"], errors="coerce"))
    if seeds != {run.seed}:
        raise SigmarlError(f"{path} holds rows of seed {', '.join(map(str, sorted(seeds)))}, not {run.seed}")
    return rows


def _top_speed(run: RunFolder) -> float:
    """The run's vehicle's top speed (env.vehicle.max_speed in its config.yaml; the default
    where the file is absent or unreadable, as for runs from before the key)."""
    path = Run(run.path).config_file
    try:
        return float(read_run_config(path).env.vehicle.max_speed) if path.is_file() else VEHICLE.max_speed
    except SigmarlError:
        return VEHICLE.max_speed


def _curve_of(run: RunFolder, model: str) -> tuple[pd.DataFrame | None, str | None]:
    """(model, seed, iteration, reward, seconds) from metrics.csv, or a note why there is none.
    seconds: the iteration's compute time (NaN where metrics.csv has no timings)."""
    path = Run(run.path).metrics_file
    if not path.is_file():
        return None, None
    # checked like a resume reads it (iterations 1..n, finite values), or one line naming the line
    history = read_training_curve(path)
    if REWARD_COLUMN not in history[0][1]:
        return None, f"{path} lacks the column {REWARD_COLUMN}: no training curve"
    metrics = pd.DataFrame([values for _, values in history]).assign(iteration=[it for it, _ in history])
    curve = pd.DataFrame({"model": model, "seed": run.seed, "iteration": metrics["iteration"].to_numpy(),
                          "reward": metrics[REWARD_COLUMN].to_numpy()})
    # the paper's definition, estimated (runs trained before it lack it: NaN)
    curve["reward_complete"] = metrics.get(COMPLETE_REWARD_COLUMN, pd.Series(float("nan"), metrics.index)).to_numpy()
    times = [c for c in TIMINGS if c in metrics.columns]
    curve["seconds"] = metrics[times].sum(axis=1).to_numpy() if times else float("nan")
    return curve, None


def _note(run: RunFolder) -> dict | None:
    """The rows' note (evaluation.json); None where it is absent or unreadable."""
    try:
        meta = json.loads(Run(run.path).rows_meta_file.read_text())
    except (OSError, ValueError):
        return None
    return meta if isinstance(meta, dict) else None


def _rules_of(run: RunFolder) -> int | None:
    """The environment rules its rows were measured under (the note's `rules`, absent before
    revision 2), or None where the folder does not say (a folder without the note)."""
    if (meta := _note(run)) is None:
        return None
    rules = meta.get("rules", 1)
    return rules if isinstance(rules, int) and not isinstance(rules, bool) else None


def _recorded_sha256(run: RunFolder) -> str | None:
    """The rows' SHA-256 their note records (`rows_sha256`), None where it records none."""
    found = (_note(run) or {}).get("rows_sha256")
    return found if isinstance(found, str) else None


def _eval_key_of(run: RunFolder) -> str | None:
    """The protocol (`eval_key.protocol_key`) its rows' note names; None where none says."""
    meta = _note(run)
    return note_protocol(meta) if meta is not None else None


def read_results(root: Path, partial: bool = False) -> FolderResults:
    """All evaluation rows and training curves of a results folder. Rows measured under older
    environment rules (`eval_key.RULES_REVISION`) or another protocol than the folder's study
    are left out, with a note. A rows file whose SHA-256 differs from its note's is refused in
    one line naming it (left out, with a note, when `partial`)."""
    runs = run_folders(root)
    frames, curves, notes = [], [], []
    keys = Counter(k for run in runs if Run(run.path).rows_file.is_file() and (k := _eval_key_of(run)))
    # the protocol most of the folder's rows were evaluated under: its study's (a sweep writes
    # every seed's rows under one; an evaluation under another is written beside them)
    study = keys.most_common(1)[0][0] if keys else None
    seen: dict[tuple[str, int], Path] = {}
    sims: dict[str | None, tuple[int, Path]] = {}  # per evaluation protocol: simulations per scenario
    unhashed = 0  # rows files whose note predates their SHA-256: checked by their contents only
    for run in runs:
        if (why := _left_out(run, study, partial)) is not None:
            notes.append(f"{run.path}: {why}")
            continue
        unhashed += Run(run.path).rows_meta_file.is_file() and _recorded_sha256(run) is None
        rows = rows_of(run)
        _same_protocol_count(rows, run, sims)
        model = str(rows["model"].iloc[0])
        if (model, run.seed) in seen:
            raise SigmarlError(f"{model} seed {run.seed} is in both {seen[(model, run.seed)]} and {run.path}")
        seen[(model, run.seed)] = run.path
        frames.append(rows)
        curve, note = _curve_of(run, model)
        curves += [curve] if curve is not None else []
        notes += [note] if note else []
    if unhashed:
        notes.append(f"{unhashed} rows file(s) under {root} have no SHA-256 in their note (written before it was "
                     "recorded): taken after checking their contents")
    if not frames:
        raise SigmarlError(f"no {ROWS_FILE} under {root}: nothing evaluated to report on"
                           + "".join(f"; {n}" for n in notes))
    curve_frame = (pd.concat(curves, ignore_index=True) if curves
                   else pd.DataFrame(columns=["model", "seed", "iteration", "reward", "seconds"]))
    return FolderResults(pd.concat(frames, ignore_index=True), curve_frame, runs, notes)


def _left_out(run: RunFolder, study: str | None, partial: bool) -> str | None:
    """Why a run's rows are left out of the report (in words), or None to read them."""
    if not Run(run.path).rows_file.is_file():
        return f"{run_state(run.path)[0]}: left out"
    rules = _rules_of(run)
    if rules is not None and rules != RULES_REVISION:
        return (f"evaluated under the environment's rules revision {rules}, not {RULES_REVISION}: left out; "
                "`sigmarl sweep runs_root=...` re-evaluates it")
    if study is not None and (theirs := _eval_key_of(run)) not in (None, study):
        return (f"evaluated under another protocol ({theirs}) than the folder's study ({study}): left out; "
                "`sigmarl sweep runs_root=...` evaluates it under the study's")
    recorded, path = _recorded_sha256(run), Run(run.path).rows_file
    if recorded is not None and hashlib.sha256(path.read_bytes()).hexdigest() != recorded:
        what = f"{path} differs from the SHA-256 its {Run(run.path).rows_meta_file.name} records (edited or damaged)"
        if not partial:
            raise SigmarlError(f"{what}; restore it, or evaluate the run again (delete it and sweep again), "
                               "or give --partial to leave it out")
        return f"{what[len(str(run.path)) + 1:]}: left out"
    return None


def _same_protocol_count(rows: pd.DataFrame, run: RunFolder, sims: dict) -> None:
    """Runs evaluated under one protocol hold the same number of simulations per scenario."""
    if "simulation" not in rows.columns or not len(rows):
        return
    key, n = _eval_key_of(run), int(rows.groupby("scenario").size().iloc[0])
    first = sims.setdefault(key, (n, run.path))
    if first[0] != n:
        raise SigmarlError(f"{run.path} holds {n} simulations per scenario, {first[1]} {first[0]} under the same "
                           "evaluation protocol: rows were dropped or added; evaluate the run again "
                           "(delete its evaluation_rows.csv and sweep again)")


def read_many(roots: list[Path], partial: bool = False) -> FolderResults:
    """`read_results` of several folders as one; a label and seed found twice is refused."""
    parts = [read_results(r, partial) for r in roots]
    rows = pd.concat([p.rows for p in parts], ignore_index=True)
    twice = rows[rows.duplicated(["model", "seed", "scenario", "simulation"])]
    if len(twice):
        raise SigmarlError(f"{twice['model'].iloc[0]} seed {twice['seed'].iloc[0]} is in more than one of "
                           f"{', '.join(map(str, roots))}")
    curves = [p.curves for p in parts if len(p.curves)]
    return FolderResults(rows, pd.concat(curves, ignore_index=True) if curves else parts[0].curves,
                         [r for p in parts for r in p.runs], [n for p in parts for n in p.notes])


def checkpoint_of(runs: list[RunFolder], model: str, name: str) -> Path | None:
    """`name` (best.pt / final.pt) of `model`'s lowest seed in the folder, if present."""
    for run in runs:
        folder = Run(run.path)
        if folder.path(name).is_file() and folder.rows_file.is_file():
            if str(rows_of(run)["model"].iloc[0]) == model:
                return folder.path(name)
    return None


def imported_folder_beside(root: Path) -> Path | None:
    """`<parent of root>/paper-policies`, where it exists."""
    folder = Path(root).resolve().parent / IMPORTED_FOLDER
    return folder if folder.is_dir() else None


def read_imported(folder: Path) -> pd.DataFrame:
    """Every `<label>/<rules>/evaluation_rows.csv` under `folder`, checked, marked imported
    (`source`), in one frame (empty where there are none)."""
    frames = []
    for path in sorted(Path(folder).glob(f"*/*/{ROWS_FILE}")):
        rows = _read_csv(path)
        missing = [c for c in ("model", "obs", "seed", "rules", "source") if c not in rows.columns]
        if missing:
            raise SigmarlError(f"{path}: rows of an imported policy lack the column(s) {', '.join(missing)}")
        paper = set(rows["rules"].astype(str)) == {"paper"}
        frames.append(check_rows(rows, path, PAPER_TOP_SPEED if paper else VEHICLE.max_speed))
    return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()
