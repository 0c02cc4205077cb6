"""`seeds=auto`'s rounds: decide every comparison at this look (the group-sequential design of
`sigmarl.stats.sequential`) and say which variants get one more seed."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import pandas as pd

from sigmarl.errors import SigmarlError
from sigmarl.metrics import BY_NAME
from sigmarl.report.compare.verdicts import Design, comparisons
from sigmarl.stats.sequential import sequential_decide


@dataclass
class Round:
    """What one look decided and what the next round trains."""

    verdicts: pd.DataFrame  # scenario, metric, variant, n_variant, n_baseline, difference, p's, level, verdict
    add: dict[str, int]  # variant (or baseline) -> seeds to add before the next look
    reasons: list[str]  # one line per decision and per seed added, to record with the run
    done: bool  # nothing left to add: all decided, or the cap reached


def key(scenario: str, metric: str, variant: str) -> str:
    return f"{scenario}/{metric}/{variant}"


def next_round(
    rows: pd.DataFrame,
    design: Design,
    n_start: int,
    previous: Mapping[str, str] | None = None,
) -> Round:
    """Decide every comparison at this look and say which seeds the next round adds.

    rows: the evaluation rows so far (model, seed, scenario, simulation, metric columns);
    n_start: the seeds per side at the first look (declared once, before it, and passed
    unchanged at every look); previous: `key(...)` -> verdict of the earlier looks (decided
    comparisons keep theirs). Pure: the caller records the reasons and trains the seeds.
    """
    if not 2 <= n_start <= design.max_seeds:
        raise SigmarlError(f"the first look needs 2 to max_seeds ({design.max_seeds}) seeds per model, got {n_start}")
    previous = dict(previous or {})
    comps = comparisons(rows, design)
    tests = [c.test for c in comps]
    directions = [BY_NAME[c.metric].direction for c in comps]
    keys = [key(c.scenario, c.metric, c.variant) for c in comps]
    verdicts, p_diff, p_eq, levels = sequential_decide(
        tests, directions, [previous.get(k) for k in keys], n_start, design.max_seeds, design.alpha
    )
    frame = pd.DataFrame({
        "scenario": [c.scenario for c in comps], "metric": [c.metric for c in comps],
        "variant": [c.variant for c in comps], "n_variant": [t.n_variant for t in tests],
        "n_baseline": [t.n_baseline for t in tests], "difference": [t.difference for t in tests],
        "p_difference": [t.p_difference for t in tests], "p_difference_holm": p_diff,
        "p_equivalence": [t.p_equivalence for t in tests], "p_equivalence_holm": p_eq,
        "nominal_level": levels, "verdict": verdicts,
    })
    reasons = []
    seeds = rows.groupby("model")["seed"].nunique().to_dict()
    add: dict[str, int] = {}
    for k, c, v, t, p in zip(keys, comps, verdicts, tests, previous_list(previous, keys), strict=True):
        where = f"{c.variant} vs {design.baseline_of(c.variant)}, {c.scenario}, {c.metric}"
        if p:
            continue
        if v != "undecided":
            reasons.append(f"{where}: {v} at {t.n_variant}/{t.n_baseline} seeds "
                           f"(difference {t.difference:+.4g}, Holm p {p_diff[keys.index(k)]:.3g}, "
                           f"equivalence p {p_eq[keys.index(k)]:.3g}, nominal level {levels[keys.index(k)]:.3g})")
        elif seeds.get(c.variant, 0) >= design.max_seeds:
            reasons.append(f"{where}: undecided at the cap of {design.max_seeds} seeds")
        else:
            add[c.variant] = 1
    for variant in list(add):
        reasons.append(f"{variant}: one more seed ({seeds.get(variant, 0) + 1}), for its undecided "
                       f"comparison(s): {', '.join(c.scenario + '/' + c.metric for c, v in zip(comps, verdicts, strict=True) if c.variant == variant and v == 'undecided')}")
    for base in dict.fromkeys(design.baseline_of(v) for v in list(add)):
        # a baseline keeps pace with the variants compared with it
        if base not in add and seeds.get(base, 0) <= max(seeds.get(v, 0) for v in add
                                                          if design.baseline_of(v) == base) < design.max_seeds:
            add[base] = 1
            reasons.append(f"{base}: one more seed ({seeds.get(base, 0) + 1}), as the baseline "
                           "of the undecided comparisons")
    return Round(frame, add, reasons, done=not add)


def previous_list(previous: Mapping[str, str], keys: Sequence[str]) -> list[str | None]:
    return [previous.get(k) if previous.get(k) not in (None, "undecided") else None for k in keys]
