"""The report's study page ("study.md"): what it compares, since a label alone (NA0.2, K4) says
not what a column changed (its contents: docs/reference/outputs.md). Its provenance section says
what each column's runs were trained on (`provenance.json`) and which columns differ in library
versions or hardware, so that such a difference is not read as the design's.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import pandas as pd

from sigmarl.config import Config
from sigmarl.identity import changed_keys, fingerprint, training_settings
from sigmarl.run import Run
from sigmarl.tracking.provenance import KEYS, PACKAGES, read

NOT_RECORDED = "not recorded"
LIBRARIES = ("python", *PACKAGES)
HARDWARE = ("cpu", "gpu")

# label -> seed -> the run folder's records (None: not recorded)
Records = Mapping[str, Mapping[int, list[dict[str, Any]] | None]]


def _value(settings: dict, key: str) -> str:
    return json.dumps(settings.get(key), default=str) if key in settings else "(unset)"


def _changes(configs: Mapping[str, Config], models: Sequence[str], baseline: str | None, quote: str = "`",
             own: str = "(baseline)", none: str = "–") -> dict[str, str]:
    """Each column with a config: the training settings it changes against the baseline's."""
    against = configs.get(baseline) if baseline else None

    def change(m: str) -> str:
        if m == baseline or against is None:
            return own if m == baseline else none
        mine = training_settings(configs[m])
        return ", ".join(f"{quote}{k}={_value(mine, k)}{quote}" for k in changed_keys(configs[m], against)) or "–"

    return {m: change(m) for m in models if m in configs}


def shared_settings(configs: Sequence[Config], defaults: Config) -> list[str]:
    """'key=value (default d)' for the training settings on which every column agrees and
    which differ from the defaults."""
    if not configs:
        return []
    first = training_settings(configs[0])
    base = training_settings(defaults)
    agreed = [k for k in changed_keys(configs[0], defaults)
              if all(_value(training_settings(c), k) == _value(first, k) for c in configs[1:])]
    return [f"`{k}={_value(first, k)}` (default {_value(base, k)})" for k in agreed]


def reward_differs(configs: Sequence[Config]) -> list[str]:
    """The reward settings (env.reward.*) in which the columns differ: their training rewards
    are then sums of different functions, not comparable."""
    return sorted({k for c in configs[1:] for k in changed_keys(configs[0], c) if k.startswith("env.reward.")})


def _span(values) -> str:
    values = sorted(set(int(v) for v in values))
    return f"{values[0]:,}" if len(values) == 1 else f"{values[0]:,}–{values[-1]:,}"


def budget(cfgs: Sequence[Config], rows: pd.DataFrame, models: Sequence[str]) -> list[str]:
    """The budget in phrases: training iterations and frames, seeds a column, the evaluation."""
    parts = []
    if cfgs:
        its = [c.ppo.iterations for c in cfgs]
        frames = [c.ppo.iterations * c.ppo.frames_per_iteration for c in cfgs]
        parts.append(f"training: {_span(its)} iterations, {_span(frames)} frames a seed")
    per_run = rows.groupby(["model", "seed", "scenario"], sort=False)["simulation"].nunique()
    scenarios = list(dict.fromkeys(rows["scenario"].astype(str)))
    steps = sorted({c.eval.steps for c in cfgs})
    steps_text = f" × {'/'.join(map(str, steps))} steps" if steps else ""
    seeds = rows.groupby("model")["seed"].nunique()
    parts.append(f"seeds: {_span(seeds[[m for m in models if m in seeds.index]])} a column")
    parts.append(f"evaluation: {len(scenarios)} scenarios ({', '.join(scenarios)}) × "
                 f"{_span(per_run)} simulations{steps_text}")
    return parts


def caption(configs: Mapping[str, Config], rows: pd.DataFrame, models: Sequence[str], baseline: str | None,
            defaults: Config) -> str:
    """The study page in one paragraph, for a LaTeX caption: each column's label and what it
    changes against the baseline, the shared settings off the defaults, the budget."""
    changes = _changes(configs, models, baseline, quote="", own="baseline", none="(no baseline)")
    shown = list(changes)
    text = "Columns: " + "; ".join(f"{m}: {c}" for m, c in changes.items()) + "." if changes else ""
    shared = shared_settings([configs[m] for m in shown], defaults)
    if shared:
        text += " All: " + ", ".join(s.replace("`", "") for s in shared) + "."
    return (text + " " + "; ".join(budget([configs[m] for m in shown], rows, models)) + ".").strip()


def study_markdown(configs: Mapping[str, Config], rows: pd.DataFrame, models: Sequence[str], baseline: str | None,
                   defaults: Config, commit: str | None, title: str = "What this report compares",
                   with_commit: bool = True) -> str:
    """The report's study page (see the module's docstring); `configs`: one training config per
    column (a run's own where it is on this machine). The same text heads table.md (`title`)."""
    changes = _changes(configs, models, baseline)
    shown = list(changes)
    lines = [f"# {title}", ""]
    lines += [f"| column | fingerprint | seeds | trained otherwise than {baseline or 'the first column'} |",
              "|---|---|---|---|"]
    for m, change in changes.items():
        seeds = sorted(set(rows.loc[rows["model"].astype(str) == m, "seed"].astype(int)))
        lines.append(f"| {m} | `{fingerprint(configs[m])}` | {len(seeds)} ({', '.join(map(str, seeds))}) | {change} |")
    missing = [m for m in models if m not in configs]
    if missing:
        lines += ["", f"No training config on this machine for {', '.join(missing)}: their settings are not shown."]
    cfgs = [configs[m] for m in shown]
    shared = shared_settings(cfgs, defaults)
    lines += ["", "## Settings every column shares, where they are not the defaults", ""]
    lines += [f"- {s}" for s in shared] or ["- none: every shared setting is the default"]
    lines += ["", "## Budget", ""]
    lines += [f"- {part}" for part in budget(cfgs, rows, models)]
    if differ := reward_differs(cfgs):
        lines += ["", f"The columns train on different rewards ({', '.join(differ)}): their training "
                  "rewards (training.md) are not comparable with each other."]
    if with_commit:  # table.md leaves it out: the same rows give the same table at any commit
        lines += ["", f"Report built at commit {commit or 'unknown (not a git checkout)'}."]
    return "\n".join(lines) + "\n"


def run_records(folders: Sequence[tuple[str, int, Path]], rows: pd.DataFrame) -> dict[str, dict[int, Any]]:
    """label -> seed -> the provenance records of each run folder whose rows the report holds."""
    have = set(zip(rows["model"].astype(str), rows["seed"].astype(int), strict=True))
    out: dict[str, dict[int, Any]] = {}
    for label, seed, path in folders:
        if (str(label), int(seed)) in have:
            out.setdefault(str(label), {})[int(seed)] = read(Run(path))
    return out


def _text(value: Any, key: str) -> str:
    if key == "sigmarl_commit":
        return str(value)[:12] if value else "unknown"
    if key == "dirty":
        return {True: "dirty", False: "clean"}.get(value, "unknown")
    return str(value)


def values(records: Mapping[int, Any] | None, key: str) -> list[str]:
    """The distinct values of `key` over a column's runs and their starts, in order of seed;
    "not recorded" for a run without the record."""
    seen = (v for seed in sorted(records or {})
            for v in ([NOT_RECORDED] if records[seed] is None else [_text(r.get(key), key) for r in records[seed]]))
    return list(dict.fromkeys(seen)) or [NOT_RECORDED]


def _differs(records: Records, models: Sequence[str], keys: Sequence[str]) -> list[str]:
    """'key: value (columns); value (columns)' for each key whose recorded values differ between
    or within columns (runs without the record left out)."""
    out = []
    for key in keys:
        by_value: dict[str, list[str]] = {}
        for m in models:
            for v in values(records.get(m), key):
                if v != NOT_RECORDED:
                    by_value.setdefault(v, []).append(m)
        if len(by_value) > 1:
            out.append(f"{key} " + "; ".join(f"{v} ({', '.join(ms)})" for v, ms in by_value.items()))
    return out


def provenance_markdown(records: Records, models: Sequence[str]) -> list[str]:
    """The study page's section: one row per recorded item, one column per model."""
    lines = ["## What the runs were trained on", ""]
    if not any(r is not None for m in models for r in (records.get(m) or {}).values()):
        return lines + [f"Provenance: {NOT_RECORDED} (every run was trained before sigmarl recorded it in "
                        "`provenance.json`)."]
    lines += ["| | " + " | ".join(models) + " |", "|---|" + "---|" * len(models)]
    lines += [f"| {key} | " + " | ".join(" / ".join(values(records.get(m), key)) for m in models) + " |"
              for key in KEYS]
    lines.append("")
    libraries, hardware = _differs(records, models, LIBRARIES), _differs(records, models, HARDWARE)
    if libraries:
        lines.append("**Trained under different library versions**: " + " · ".join(libraries) + ".")
    if hardware:
        lines.append("**Trained on different hardware**: " + " · ".join(hardware) + ".")
    if not libraries and not hardware:
        lines.append("Every recorded run used the same library versions and hardware.")
    if missing := [m for m in models if NOT_RECORDED in values(records.get(m), "python")]:
        lines.append(f"Runs of {', '.join(missing)} are {NOT_RECORDED} (trained before sigmarl recorded it).")
    return lines
