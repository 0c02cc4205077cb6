"""Which runs a report shows under each column, and which it leaves out.

A column is a config, not a label (docs/concepts.md, Fingerprint): a run under a variant's label
trained otherwise than the variant composes to is refused in one line, or left out with
--partial. Every run of the study's variants without rows in the report is named (failed,
not evaluated, unfinished, never run); a failed run, or a declared variant whose runs have no
rows, ends the report unless --partial.
"""

from __future__ import annotations

import json
from collections import Counter
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from sigmarl.config import Config
from sigmarl.errors import SigmarlError
from sigmarl.identity import changed_keys, differences, training_settings
from sigmarl.run import Run


def variant_configs(overrides: Sequence[str], variants: dict[str, list[str]],
                    labels: Sequence[str]) -> dict[str, Config]:
    """label -> the training config the study's variant composes to under the report's overrides,
    for the declared variants among `labels` (a label a sweep derived, e.g. M0_hidden-64-64, has
    no declaration to compose)."""
    # lazy: Hydra only where a report reads runs of a declared study
    from sigmarl.compose import compose_config

    keep = [o for o in overrides if not o.lstrip("+~").startswith(("model=", "seed="))]
    return {label: compose_config([*keep, *variants[label], f"model={label}"])
            for label in dict.fromkeys(labels) if label in variants}


def _changes(own: Config | None, cfg: Config, fp: str) -> frozenset:
    """What a run's training config sets otherwise than its variant's composition, as
    (key, its value) pairs; a run whose config is not on this machine is its fingerprint alone."""
    if fp == cfg.fingerprint:
        return frozenset()
    if own is None:
        return frozenset({("fingerprint", fp)})
    mine = training_settings(own)
    return frozenset((k, json.dumps(mine.get(k), default=str)) for k in changed_keys(own, cfg))


def check_columns(rows: pd.DataFrame, expected: dict[str, Config], partial: bool,
                  recorded: Callable[[str], Config | None] = lambda run: None) -> tuple[pd.DataFrame, list[str]]:
    """The rows without those of runs trained otherwise than their column's siblings, and the
    report's notes; refused in one line where any is, unless `partial`.

    Each run's changes against its variant's composition are compared: runs whose changes are
    the ones every other column shares (a sweep's command line, e.g. ppo=smoke, that the report
    was not given) are kept; a run whose changes are its own (a quick-budget M0 beside the
    paper's M4, or two budgets in one column) is not its variant. `recorded(run)` gives a run's
    training config from the row's `eval_run_id`."""
    if "fingerprint" not in rows or not expected:
        return rows, []
    fp = rows["fingerprint"].fillna("").astype(str)
    ours = rows["model"].astype(str).isin(list(expected)) & (fp != "")  # untagged (older) runs: kept
    groups = {}
    for (label, seed, other), group in rows[ours].groupby(["model", "seed", "fingerprint"], sort=True):
        own = recorded(str(group["eval_run_id"].iloc[0])) if "eval_run_id" in group else None
        groups[(label, seed, other)] = (own, _changes(own, expected[label], other))
    signatures = Counter(changes for _, changes in groups.values())
    shared = frozenset() if frozenset() in signatures else (signatures.most_common(1)[0][0] if signatures else None)
    # changes count as the study's command line where two columns or more share them, or where
    # the runs were trained in this very study; a lone column of another study's runs (a quick M0
    # evaluated into the paper study's store) shows nothing shared: it is not the variant
    having = [(label, own) for (label, _, _), (own, changes) in groups.items() if changes == shared]
    if shared and len({label for label, _ in having}) < 2 and not all(
            own is not None and own.study.name == expected[label].study.name for label, own in having):
        shared = None
    lines, bad = [], pd.Series(False, index=rows.index)
    for (label, seed, other), (own, changes) in groups.items():
        if changes == shared:
            continue
        cfg = expected[label]
        what = f": {differences(own, cfg)}" if own is not None else ""
        lines.append(f"{label} seed {seed} was trained with fingerprint {other}, not the variant's "
                     f"{cfg.fingerprint}{what}")
        bad |= (rows["model"].astype(str) == label) & (rows["seed"] == seed) & (fp == other)
    if lines and not partial:
        more = f" (and {len(lines) - 1} more)" if len(lines) > 1 else ""
        raise SigmarlError(f"{lines[0]}{more}: it is not that variant; report the study it was trained in, "
                           "give the same overrides it was trained with, or --partial to leave it out")
    return rows[~bad].reset_index(drop=True), [f"Left out: {line} (not this column's config)." for line in lines]


def one_config_per_run(rows: pd.DataFrame, declared: Sequence[str] = ()) -> pd.DataFrame:
    """Where one (model, seed) of a label without a declared variant to choose by was evaluated
    under several training configs, the newest evaluation's (rows in evaluation order)."""
    if "fingerprint" not in rows or not len(rows):
        return rows
    newest = rows.groupby(["model", "seed"], sort=False)["fingerprint"].transform("last")
    keep = (rows["fingerprint"] == newest) | rows["model"].astype(str).isin(list(declared))
    return rows[keep].reset_index(drop=True)


@dataclass(frozen=True)
class LeftOut:
    label: str
    seed: int | None  # None: the variant has no run folder at all
    why: str  # "failed: <error>", "trained, not evaluated yet", ...
    failed: bool = False

    def __str__(self) -> str:
        return f"{self.label}{'' if self.seed is None else f' seed {self.seed}'} {self.why}"


def run_state(path: Path) -> tuple[str, bool]:
    """Why a run folder has no rows in the report (its files alone), and whether it failed."""
    run = Run(path)
    if (failure := run.failure()) is not None:
        return f"failed: {failure}", True
    if run.rows_file.is_file():
        return "evaluated, but its rows are not in the report's source", False
    if run.final_file.is_file():
        return "trained, not evaluated yet", False
    if run.resume_file.is_file() or run.metrics_file.is_file():
        return f"not evaluated yet, training unfinished (no {run.final_file.name})", False
    return "not evaluated yet, training never started", False


def left_out(variants: Sequence[str], reported: set[tuple[str, int]],
             folders: Iterable[tuple[str, int, Path]], where: str, declared: bool = True) -> list[LeftOut]:
    """The study's runs not in the report: each run folder (label, seed, path) of one of
    `variants` whose (label, seed) has no rows in it and, where the study `declared` them, each
    variant that has neither rows nor a run folder (`where`: where its folders were looked for)."""
    out, seen = [], set()
    for label, seed, path in folders:
        if label not in variants:  # a label a command-line sweep derived (M0_hidden-64-64) is its own
            continue
        seen.add(label)
        if (label, seed) not in reported:
            why, failed = run_state(path)
            out.append(LeftOut(label, seed, why, failed))
    if declared:
        have = {label for label, _ in reported} | seen
        never = [v for v in variants if v not in have]
        if never:
            out.append(LeftOut(", ".join(never), None, f"not run (no rows, no run folder in {where})"))
    return out


def check(declared: Sequence[str], reported: set[tuple[str, int]], missing: list[LeftOut],
          study: str, partial: bool) -> None:
    """What the report leaves out, refused in one line unless `partial` where a run
    failed, or a declared variant has run folders but no rows (unfinished, not evaluated). A
    variant never run (no folder, no rows: e.g. `sweep models=[...]` picked others) is a note."""
    started = {m.label for m in missing if m.seed is not None}
    rowless = [v for v in declared if v in started and v not in {label for label, _ in reported}]
    failed = [m for m in missing if m.failed]
    if (rowless or failed) and not partial:
        what = []
        if rowless:
            what.append(f"{', '.join(rowless)} of study {study!r} {'has' if len(rowless) == 1 else 'have'} "
                        "no evaluation rows")
        if failed:
            what.append(f"{len(failed)} run(s) failed")
        raise SigmarlError(f"{' and '.join(what)}: {'; '.join(map(str, missing))}. Fix it and run the "
                           "sweep again, or give --partial to report the rest")
