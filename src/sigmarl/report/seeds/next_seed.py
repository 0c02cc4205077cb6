"""Where a next seed will land, and how many seeds are slow: the small-n practice of reporting
seed-to-seed spread as intervals for one more run, not only for the mean.

Prediction interval (per model and scenario, CR_total): normal theory, mean +- t_{n-1} s
sqrt(1 + 1/n), its low end clipped at 0 (a rate); beside it the seeds' range [min, max], which
holds a next seed with probability (n-1)/(n+1) whatever the seeds' distribution (so 95 % needs
39 seeds; our seed means are skewed, so the normal interval's 95 % is an approximation).

Slow seeds: where the study declares `slow_seed` (a CR_total in %), a seed whose worst scenario
exceeds it is slow; each variant's proportion is compared with its baseline's by Fisher's exact
test (two-sided), the test for proportions of a few seeds.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
from scipy import stats

from sigmarl.report.tables import p_text

LEVEL = 0.95
PREDICTION_COLUMNS = ["model", "scenario", "n_seeds", "mean", "sd", "pi_low", "pi_high", "min", "max",
                      "range_coverage"]
SLOW_COLUMNS = ["model", "baseline", "threshold", "slow", "seeds", "baseline_slow", "baseline_seeds", "p_fisher"]


def prediction_table(seeds: pd.DataFrame, scenarios: list[str], level: float = LEVEL) -> pd.DataFrame:
    """Per model and scenario with at least 2 seeds: the next seed's CR_total interval."""
    records = []
    for model, g in seeds.groupby("model", sort=False):
        for scenario in scenarios:
            x = g[f"CR_total_{scenario}"].dropna().to_numpy(float)
            n = len(x)
            if n < 2:
                continue
            mean, sd = float(x.mean()), float(x.std(ddof=1))
            half = stats.t.ppf(0.5 + level / 2, n - 1) * sd * math.sqrt(1 + 1 / n)
            records.append({"model": model, "scenario": scenario, "n_seeds": n, "mean": mean, "sd": sd,
                            "pi_low": max(0.0, mean - half), "pi_high": mean + half, "min": float(x.min()),
                            "max": float(x.max()), "range_coverage": (n - 1) / (n + 1)})
    return pd.DataFrame(records, columns=PREDICTION_COLUMNS)


def slow_seed_table(seeds: pd.DataFrame, baseline_of: dict[str, str], threshold: float) -> pd.DataFrame:
    """Per compared variant: its slow seeds (worst CR_total above `threshold`) against its
    baseline's, with Fisher's exact p. Empty where the threshold is 0 (not declared)."""
    if threshold <= 0:
        return pd.DataFrame(columns=SLOW_COLUMNS)
    worst = seeds.groupby("model", sort=False)["CR_total_worst"]
    counts = {m: (int((w > threshold).sum()), int(w.notna().sum())) for m, w in worst}
    records = []
    for model, baseline in baseline_of.items():
        if model not in counts or baseline not in counts:
            continue
        (a, n), (b, m) = counts[model], counts[baseline]
        p = float(stats.fisher_exact([[a, n - a], [b, m - b]]).pvalue)
        records.append({"model": model, "baseline": baseline, "threshold": threshold, "slow": a, "seeds": n,
                        "baseline_slow": b, "baseline_seeds": m, "p_fisher": p})
    return pd.DataFrame(records, columns=SLOW_COLUMNS)


def next_seed_markdown(prediction: pd.DataFrame, slow: pd.DataFrame, scenarios: list[str]) -> str:
    """The two tables as Markdown (empty where neither has rows)."""
    lines: list[str] = []
    if len(prediction):
        cells = prediction.set_index(["model", "scenario"])
        lines += [
            f"Where a next seed's CR_total (%) will land, per scenario ({' / '.join(scenarios)}): the "
            f"{LEVEL:.0%} prediction interval (normal theory, mean ± t s √(1 + 1/n)) and the seeds' "
            "range [min, max], which holds a next seed with probability (n − 1)/(n + 1) whatever the "
            "distribution:",
            "",
            "| Model | seeds | prediction interval | range (its coverage) |",
            "|---|---:|---|---|",
        ]
        for model in dict.fromkeys(prediction["model"]):
            mine = [cells.loc[(model, s)] for s in scenarios if (model, s) in cells.index]
            pi = " / ".join(f"[{r['pi_low']:.2f}, {r['pi_high']:.2f}]" for r in mine)
            ranges = " / ".join(f"[{r['min']:.2f}, {r['max']:.2f}]" for r in mine)
            n = int(np.max([r["n_seeds"] for r in mine]))
            lines.append(f"| {model} | {n} | {pi} | {ranges} ({(n - 1) / (n + 1):.0%}) |")
        lines.append("")
    if len(slow):
        threshold = float(slow["threshold"].iloc[0])
        lines += [
            f"Slow seeds (worst CR_total over the scenarios above {threshold:g} %), each variant against "
            "its baseline by Fisher's exact test (two-sided, unadjusted):",
            "",
            "| Model | slow | baseline | baseline slow | p |",
            "|---|---:|---|---:|---:|",
        ]
        for r in slow.to_dict("records"):
            lines.append(f"| {r['model']} | {r['slow']} of {r['seeds']} | {r['baseline']} | "
                         f"{r['baseline_slow']} of {r['baseline_seeds']} | {p_text(r['p_fisher'])} |")
        lines.append("")
    return "\n".join(lines)
