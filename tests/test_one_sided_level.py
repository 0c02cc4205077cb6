"""The replication verdicts' one-sided permutation tests (tests/permutation_reference.py): their level,
simulated with fixed seeds at the seed counts of the committed study (5, 6 and 14 a model).

- Under nulls whose two sides' seeds come from one distribution (lognormal, a slow-seed mixture,
  the committed M0 and M4 seeds pooled), moved to the null's boundary (the variant's seeds
  shifted by the tested difference), the rejection rate at nominal 5 % stays within 3 binomial
  standard errors above 5 %.
- Under unequal shapes with equal means (M4's committed seeds moved onto M0's mean, against M0's)
  neither the plain statistic nor Welch's t (the studentized permutation test) keeps the level at
  these n: that is measured here and stated in docs/concepts.md, and why the replication
  verdicts keep the verdicts' own statistic.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from permutation_reference import greater_p, less_p
from test_permutation_level import committed_seed_means, draw

ALPHA = 0.05
REPS = 1200
SHIFT = 0.4  # a tested difference (pp), like the paper's M4 - M0
EXACT = 40_000  # splits enumerated up to this many (6 against 14: 38,760), else 20,000 random
# The measured rates under unequal shapes (one-sided "less", M4's shape against M0's, On-Ramp,
# 6 against 14 seeds), as docs/concepts.md states them
UNEQUAL = {"difference": 0.46, "welch": 0.40}


def rejection_rate(null: str, na: int, nb: int, seed: int, alternative: str) -> float:
    rng = np.random.default_rng(seed)
    a, b = draw(rng, null, (REPS, na), 2), draw(rng, null, (REPS, nb), 2)
    test = greater_p if alternative == "greater" else less_p
    return float(np.mean(test(a + SHIFT, b, SHIFT, exact_limit=EXACT) <= ALPHA))


@pytest.mark.parametrize("null", ["lognormal", "slow seed", "committed"])
@pytest.mark.parametrize("na, nb", [(5, 5), (6, 14), (14, 14)])
@pytest.mark.parametrize("alternative", ["greater", "less"])
def test_one_sided_keeps_the_level(null, na, nb, alternative):
    rate = rejection_rate(null, na, nb, 11 + na + nb, alternative)
    assert rate <= ALPHA + 3 * math.sqrt(ALPHA * (1 - ALPHA) / REPS)


def test_unequal_shapes_break_either_statistic_as_the_docs_say():
    m0, m4 = committed_seed_means()[("M0", "On-Ramp")], committed_seed_means()[("M4", "On-Ramp")]
    rng = np.random.default_rng(5)
    a, b = rng.choice(m4 - m4.mean() + m0.mean(), (REPS, 6)), rng.choice(m0, (REPS, 14))
    docs = (Path(__file__).resolve().parents[1] / "docs" / "concepts.md").read_text(encoding="utf-8")
    for statistic, stated in UNEQUAL.items():
        rate = float(np.mean(less_p(a, b, 0.0, statistic, exact_limit=EXACT) <= ALPHA))
        assert rate == pytest.approx(stated, abs=3 * math.sqrt(stated * (1 - stated) / REPS)), statistic
        assert rate > 0.06  # the level does not hold
        assert f"{stated:.2f}" in docs
