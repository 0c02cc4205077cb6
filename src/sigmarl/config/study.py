"""An ablation study as data (`study.*`, conf/study/<name>.yaml) and how a sweep packs its jobs
(`sweep.*`)."""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass, field

from sigmarl.ablation import PAPER_SCENARIOS
from sigmarl.config.ranges import SEED_MAX, ranged
from sigmarl.errors import SigmarlError
from sigmarl.metrics import AS, CD, CR_TOTAL, HEADLINE


@dataclass
class StudyConfig:
    """An ablation study as data (conf/study/<name>.yaml): which training configs it compares,
    with which seeds, on which scenarios, and how it decides."""

    name: str = "paper"
    """The study's name (conf/study/<name>.yaml)."""
    variants: dict[str, list[str]] = field(default_factory=dict)
    """Label -> Hydra overrides of the training config, in table order; a label names run folders and a column."""
    baseline: str = "M0"
    """The variant every other variant is compared with."""
    baselines: dict[str, str] = field(default_factory=dict)
    """Variant -> its own baseline where it is not `baseline` (a factorial study: {M4-paper: M0-paper})."""
    interactions: dict[str, list[str]] = field(default_factory=dict)
    """Name -> [x, y]: does x's comparison with its baseline differ from y's with its own?"""
    seeds: list[int] = ranged(factory=lambda: [0], lo=0, hi=SEED_MAX)
    """Seeds of every variant (seeds=[0,1,2] on the command line)."""
    scenarios: list[str] = field(default_factory=lambda: list(PAPER_SCENARIOS))
    """The scenarios every variant is evaluated on."""
    metrics: list[str] = field(default_factory=lambda: [HEADLINE])
    """The metrics each comparison decides on."""
    margins: dict[str, float] = ranged(factory=lambda: {CR_TOTAL: 0.1, CD: 0.1, AS: 0.01}, lo=0, lo_open=True)
    """Equivalence margins per metric, in the table's units (percentage points, cm, m/s)."""
    max_seeds: int = ranged(10, lo=2, hi=10**4, size=True)
    """seeds=auto adds seeds up to this many per variant."""
    slow_seed: float = ranged(0.0, lo=0, hi=100)
    """A seed whose worst CR_total (%) over the scenarios exceeds this is slow; the report counts them per variant and tests each against its baseline (Fisher's exact). 0: off."""
    checkpoints_from: str = ""
    """A folder of trained runs (<label>/seed<k>/) to evaluate instead of training (e.g. results/paper-budget)."""
    job: str = ""
    """Set by `sigmarl sweep` for its jobs: this job's key in the plan file."""
    plan: str = ""
    """Set by `sigmarl sweep` for its jobs: the plan file."""


@dataclass
class SweepConfig:
    """How `sigmarl sweep` packs its jobs (not a training setting: no fingerprint sees it)."""

    seeds_per_job: int = ranged(0, lo=0, hi=4096, size=True)
    """Seeds of one variant each sweep job trains as one seed block (`sigmarl train seeds=[...]`). 0: by device, 1 on cpu (measured: a block seed costs 0.88-1.07 of a lone one there, benchmarks/bench_blocks.py), 64 on cuda (estimated; not yet measured)."""


def seed_list(values: Sequence[object]) -> list[int]:
    """The seeds that `seeds=[...]` (or `seeds=range(a,b)`, `seed=a,b`) lists, as Hydra's
    override parser read them: distinct whole numbers in the range of `seed`, at least one; the
    one reader of those values (`sigmarl train`'s seed block, a sweep's seeds). Otherwise one
    line naming the bad value."""
    out = []
    for value in values:
        text = str(value).strip()
        if isinstance(value, bool) or not re.fullmatch(r"\d{1,10}", text) or int(text) > SEED_MAX:
            raise SigmarlError(f"seeds: {text!r} is not a seed: seeds=[...] lists non-negative integers up to "
                               f"{SEED_MAX}, e.g. seeds=[0,1,2]")
        out.append(int(text))
    if not out:
        raise SigmarlError("seeds=[] lists no seed: seeds=[...] lists non-negative integers, e.g. seeds=[0,1,2]")
    if len(set(out)) < len(out):
        raise SigmarlError(f"seeds=... lists a seed twice: {out}")
    return out
