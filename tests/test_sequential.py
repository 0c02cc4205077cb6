"""seeds=auto's error control: simulated studies whose truth is set.

Each simulated study compares one variant with the baseline on CR_total-like data: a seed's
collision rate is the baseline's times a log-normal seed effect (plus the variant's true
shift), and each of its 32 simulations counts Poisson collisions over 1200 steps, so the
values are nonnegative, skewed and often zero, and seeds differ far more than simulations,
as in results/paper-budget. Rounds add one seed per side from 3 up to 10 and stop at the
first verdict.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from sigmarl.report.compare.verdicts import Design, decide
from sigmarl.report.plan import (
    boundaries,
    next_round,
    nominal_levels,
    obrien_fleming_spending,
    sequential_decide,
)
from sigmarl.stats.engine import welch

N_START, MAX_SEEDS, ALPHA = 3, 10, 0.05
SIMS, STEPS = 32, 1200
BASE_RATE = 0.004  # 0.4 % of steps, M0's order of magnitude
MARGIN = 0.3  # percentage points; wide enough that equivalence is reachable within 10 seeds
LOWER_IS_BETTER = -1


def seed_means(rng: np.random.Generator, reps: int, shift_pct: float) -> np.ndarray:
    """[reps, MAX_SEEDS] seed means of CR_total in %, the true mean shifted by shift_pct."""
    effect = rng.lognormal(-0.08, 0.4, (reps, MAX_SEEDS, 1))  # mean ~1: seed-to-seed spread
    rate = BASE_RATE * effect + shift_pct / 100
    counts = rng.poisson(rate * STEPS, (reps, MAX_SEEDS, SIMS))
    return (counts / STEPS * 100).mean(-1)


def run_studies(shift_pct: float, reps: int, seed: int) -> tuple[list[str], list[str]]:
    """The first verdict of each simulated study: with the sequential design, and with the
    same rounds tested at alpha at every look (no correction)."""
    rng = np.random.default_rng(seed)
    base, variant = seed_means(rng, reps, 0.0), seed_means(rng, reps, shift_pct)
    corrected, naive = [], []
    for r in range(reps):
        seq = plain = None
        for n in range(N_START, MAX_SEEDS + 1):
            test = welch(variant[r, :n], base[r, :n], MARGIN)
            if seq is None:
                v = sequential_decide([test], [LOWER_IS_BETTER], [None], N_START, MAX_SEEDS, ALPHA)[0][0]
                seq = None if v == "undecided" else v
            if plain is None:
                v = decide([test], [LOWER_IS_BETTER], ALPHA)[0][0]
                plain = None if v == "undecided" else v
            if seq and plain:
                break
        corrected.append(seq or "undecided")
        naive.append(plain or "undecided")
    return corrected, naive


def rate(verdicts: list[str], wrong: set[str]) -> float:
    return float(np.mean([v in wrong for v in verdicts]))


def test_equal_variants_are_rarely_called_different():
    corrected, naive = run_studies(0.0, reps=400, seed=1)
    assert rate(corrected, {"better", "worse"}) <= 0.05
    assert rate(naive, {"better", "worse"}) > 0.05  # the repeated looks do inflate it
    assert rate(corrected, {"equivalent"}) > 0.2  # and the design still decides


def test_a_difference_at_the_margin_is_rarely_called_equivalent():
    # the variant collides MARGIN percentage points more: equivalence is false, and it is
    # hardest to tell at exactly the margin
    corrected, naive = run_studies(MARGIN, reps=400, seed=2)
    assert rate(corrected, {"equivalent", "better"}) <= 0.05
    assert rate(naive, {"equivalent", "better"}) > 0.05
    assert rate(corrected, {"worse"}) > 0.2


def test_obrien_fleming_boundaries_match_the_published_table():
    # Lan-DeMets O'Brien-Fleming spending, 5 equally spaced looks, two-sided 0.05:
    # 4.877, 3.357, 2.680, 2.290, 2.031 (DeMets & Lan 1994; gsDesign's sfLDOF, one-sided 0.025)
    c = boundaries((0.2, 0.4, 0.6, 0.8, 1.0), 0.05, 2)
    assert c == pytest.approx([4.877, 3.357, 2.680, 2.290, 2.031], abs=3e-3)
    assert obrien_fleming_spending(1.0, 0.05) == pytest.approx(0.05)
    # half the information: 4 (1 - Phi(z_0.9875 / sqrt(0.5))) = 4 (1 - Phi(3.170)), Phi(3.17) = 0.999238
    assert obrien_fleming_spending(0.5, 0.05) == pytest.approx(4 * (1 - 0.999238), abs=2e-5)


def test_nominal_levels_rise_towards_alpha():
    levels = nominal_levels(N_START, MAX_SEEDS, ALPHA)
    two = [levels[n][0] for n in range(N_START, MAX_SEEDS + 1)]
    assert all(a < b for a, b in zip(two, two[1:], strict=False))
    assert two[0] < 0.001 and 0.03 < two[-1] < ALPHA


def _rows(values: dict[str, np.ndarray]) -> pd.DataFrame:
    """Evaluation rows of the models' [seeds, sims] CR_total (fractions of steps)."""
    records = []
    for model, v in values.items():
        for seed in range(v.shape[0]):
            for sim in range(v.shape[1]):
                records.append({"model": model, "seed": seed, "scenario": "CPM", "simulation": sim,
                                "CR_total": v[seed, sim], "CD": 1.0, "AS": 0.7})
    return pd.DataFrame(records)


def test_next_round_adds_seeds_to_undecided_variants_and_the_baseline():
    # 7 seeds a side: the permutation test cannot show a difference at the first looks
    # (its smallest p, 2 / C(2n, n), lies above their nominal levels up to 5 seeds)
    rng = np.random.default_rng(3)
    base = rng.poisson(5, (7, 8)) / STEPS
    values = {"M0": base, "M1": base + 0.2, "M2": rng.poisson(5, (7, 8)) / STEPS}
    design = Design(variants=["M0", "M1", "M2"], max_seeds=MAX_SEEDS)
    first = next_round(_rows(values), design, N_START)
    verdicts = dict(zip(first.verdicts["variant"], first.verdicts["verdict"], strict=True))
    assert verdicts["M1"] == "worse"  # 20 percentage points more collisions in every seed
    assert verdicts["M2"] == "undecided"
    assert first.add == {"M2": 1, "M0": 1}
    assert not first.done and any(line.startswith("M1 vs M0, CPM, CR_total: worse") for line in first.reasons)
    # the next look keeps M1's verdict, whatever its new data say
    values = {m: np.vstack([v, rng.poisson(5, (1, 8)) / STEPS]) if m != "M1" else v for m, v in values.items()}
    previous = {f"CPM/CR_total/{v}": verdicts[v] for v in verdicts}
    second = next_round(_rows(values), design, N_START, previous)
    assert dict(zip(second.verdicts["variant"], second.verdicts["verdict"], strict=True))["M1"] == "worse"


def test_next_round_adds_a_seed_to_each_undecided_variants_own_baseline():
    """With its own baselines (M4 against M0, M4-paper against M0-paper), an undecided variant
    brings its own baseline along, and only that one."""
    rng = np.random.default_rng(5)
    noise = {m: rng.poisson(5, (7, 8)) / STEPS for m in ("M0", "M4", "M0-paper")}
    values = {**noise, "M4-paper": noise["M0-paper"] + 0.2}  # decided: worse in every seed
    design = Design(variants=["M0-paper", "M4-paper", "M0", "M4"], baseline="M0-paper",
                    baselines={"M4": "M0"}, max_seeds=MAX_SEEDS)
    r = next_round(_rows(values), design, N_START)
    verdicts = dict(zip(r.verdicts["variant"], r.verdicts["verdict"], strict=True))
    assert verdicts["M4-paper"] == "worse"
    assert verdicts["M4"] == "undecided" and verdicts["M0"] == "undecided"
    # M0 (undecided against M0-paper) and M4 (against M0) add a seed; M0-paper keeps pace with M0
    assert r.add == {"M0": 1, "M4": 1, "M0-paper": 1}
    assert any(line.startswith("M4 vs M0, CPM, CR_total") or line.startswith("M4:") for line in r.reasons)


def test_next_round_stops_at_the_cap():
    rng = np.random.default_rng(4)
    values = {"M0": rng.poisson(5, (3, 8)) / STEPS, "M2": rng.poisson(5, (3, 8)) / STEPS}
    design = Design(variants=["M0", "M2"], max_seeds=3)
    r = next_round(_rows(values), design, 3)
    assert r.done and r.add == {}
    assert r.reasons == ["M2 vs M0, CPM, CR_total: undecided at the cap of 3 seeds"]
    # a single look (n_start = max_seeds) spends all of alpha at it
    assert r.verdicts["nominal_level"].iloc[0] == pytest.approx(ALPHA, abs=1e-4)


@pytest.mark.slow
def test_four_equal_variants_sharing_the_baseline_keep_the_family_wise_rate():
    # Holm over the study's comparisons at every look: with four variants equal to the baseline
    # (one baseline's seeds shared by all four tests), any false better/worse counts once
    k, reps = 4, 300
    rng = np.random.default_rng(7)
    false_seq = false_naive = 0
    for _ in range(reps):
        base, variants = seed_means(rng, 1, 0.0)[0], seed_means(rng, k, 0.0)
        seq: list[str | None] = [None] * k
        naive: list[str | None] = [None] * k
        for n in range(N_START, MAX_SEEDS + 1):
            tests = [welch(variants[i, :n], base[:n], MARGIN) for i in range(k)]
            v = sequential_decide(tests, [LOWER_IS_BETTER] * k, seq, N_START, MAX_SEEDS, ALPHA)[0]
            seq = [x if x != "undecided" else None for x in v]
            plain = decide(tests, [LOWER_IS_BETTER] * k, ALPHA)[0]
            naive = [p or (x if x != "undecided" else None) for p, x in zip(naive, plain, strict=True)]
            if all(seq) and all(naive):
                break
        false_seq += any(x in ("better", "worse") for x in seq)
        false_naive += any(x in ("better", "worse") for x in naive)
    assert false_seq / reps <= 0.05 < false_naive / reps


def test_next_round_rejects_a_first_look_outside_the_design():
    from sigmarl.errors import SigmarlError

    values = {"M0": np.zeros((3, 2)), "M2": np.zeros((3, 2))}
    with pytest.raises(SigmarlError, match="the first look needs 2 to max_seeds"):
        next_round(_rows(values), Design(variants=["M0", "M2"], max_seeds=10), 11)
