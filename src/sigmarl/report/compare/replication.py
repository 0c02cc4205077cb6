"""Does the paper's ablation reproduce? One verdict per claim of its Table I.

The paper trained one seed per model, so each of its differences (Mk - M0, CR_total, per
scenario) is one draw of "one seed of Mk minus one seed of M0". Per claim, from our seed means
(collision rates trimmed as the paper's: each evaluation's best and worst simulation dropped):

- our difference d (mean of seed means, Mk minus M0) with Welch's 95 % interval;
- where the paper's difference D falls among our one-seed-minus-one-seed differences (every
  pair of a seed of Mk and a seed of M0): its percentile (ties count half) and whether it lies
  inside their central 95 %; outside, seed luck does not explain it;
- four one-sided permutation tests of the difference of seed means (`sigmarl.stats.one_sided`,
  the verdicts' own statistic), in the paper's direction s = sign(D): shown in its direction (H0 s d <= 0), reversed (H0 s d >= 0), smaller
  than the paper's (H0 s d >= |D|) and larger (H0 s d <= |D|), each kind Holm-adjusted over the
  claims.

Verdict, in order: **reversed** (reversed shown); **reproduced, smaller** / **reproduced,
larger** (direction shown, and smaller / larger shown); **reproduced** (direction shown);
**not reproduced** (smaller shown, direction not); else **undecided**, with the seeds per model
for power 0.8 to tell a true difference of D from none at Holm's level for the claims still open
(the planning of `--plan` at delta = D).

Ranking claims: the model with the paper's best composite score on each scenario; the share of
whole-seed bootstrap replicates (each model's seeds drawn with replacement, a drawn seed bringing
all its scenarios; composite normalisers recomputed per replicate) in which that model ranks first
here; reproduced at >= 1 - alpha, not reproduced at <= alpha, else undecided.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from sigmarl.metrics import COMPOSITE
from sigmarl.report.compare.verdicts import seed_values
from sigmarl.report.format import p_text, signed
from sigmarl.report.table.aggregate import trim_collisions
from sigmarl.report.table.paper import paper_values
from sigmarl.stats import bootstrap as bs
from sigmarl.stats.one_sided import greater_p, less_p
from sigmarl.stats.power import seeds_for_difference
from sigmarl.stats.tests import holm, welch
from sigmarl.stats.variance import components

METRIC = "CR_total"
N_BOOT = 2000
COLUMNS = [
    "claim", "scenario", "metric", "model", "baseline", "n_model", "n_baseline", "paper", "ours",
    "ci_low", "ci_high", "pair_percentile", "pair_low", "pair_high", "paper_inside_pairs",
    "p_direction", "p_direction_holm", "p_reversed", "p_reversed_holm", "p_smaller", "p_smaller_holm",
    "p_larger", "p_larger_holm", "verdict", "explanation", "seeds_needed", "probability_first",
    "most_often_first",
]  # fmt: skip
KINDS = ("direction", "reversed", "smaller", "larger")


def pair_position(mine: np.ndarray, base: np.ndarray, paper: float) -> tuple[float, float, float]:
    """The paper's difference among every one-seed-minus-one-seed difference of our seed means:
    its percentile (ties half) and the pairs' central 95 % (2.5th and 97.5th percentiles)."""
    pairs = (mine[:, None] - base[None, :]).ravel()
    below, tied = np.count_nonzero(pairs < paper), np.count_nonzero(pairs == paper)
    low, high = np.percentile(pairs, [2.5, 97.5])
    return 100.0 * (below + 0.5 * tied) / len(pairs), float(low), float(high)


def one_sided(mine: np.ndarray, base: np.ndarray, paper: float) -> dict[str, float]:
    """The four one-sided p-values of a claim, in the paper's direction."""
    s = 1.0 if paper >= 0 else -1.0
    a, b, size = s * mine, s * base, abs(paper)
    return {"direction": greater_p(a, b, 0.0), "reversed": less_p(a, b, 0.0),
            "smaller": less_p(a, b, size), "larger": greater_p(a, b, size)}


def decide(p: dict[str, float], alpha: float) -> str:
    """The verdict of one claim from its Holm-adjusted p-values (`KINDS`)."""
    if p["reversed"] <= alpha:
        return "reversed"
    if p["direction"] <= alpha:
        if p["smaller"] <= alpha:
            return "reproduced, smaller"
        return "reproduced, larger" if p["larger"] <= alpha else "reproduced"
    return "not reproduced" if p["smaller"] <= alpha else "undecided"


def explain(verdict: str, inside_pairs: bool) -> str:
    """What a claim that does not reproduce is attributed to from this study's seeds alone: seed
    luck where the paper's one-seed difference lies inside our pairs' central 95 %, else not
    (whether the paper's rules explain it is the rules study's interaction, not this table's)."""
    if verdict.startswith("reproduced"):
        return "–"
    return "seed luck" if inside_pairs else "not seed luck"


def difference_claims(rows: pd.DataFrame, models: list[str], baseline: str, alpha: float = 0.05,
                      power: float = 0.8) -> pd.DataFrame:
    """One row per (scenario, model) claim of the paper's CR_total differences (`COLUMNS`)."""
    paper = paper_values()
    values = seed_values(rows, METRIC)
    records = []
    for scenario in dict.fromkeys(rows["scenario"]):
        for model in models:
            key = (scenario, METRIC)
            if model == baseline or key not in paper.index or model not in paper.columns:
                continue
            groups, base_groups = values.get((model, scenario)), values.get((baseline, scenario))
            if not groups or not base_groups or len(groups) < 2 or len(base_groups) < 2:
                continue
            mine = np.array([g.mean() for g in groups])
            base = np.array([g.mean() for g in base_groups])
            claimed = float(paper.loc[key, model] - paper.loc[key, baseline])
            test = welch(mine, base, 0.0)
            lo, hi = test.interval(1 - alpha)
            pct, pair_lo, pair_hi = pair_position(mine, base, claimed)
            record = {"claim": "difference", "scenario": scenario, "metric": METRIC, "model": model,
                      "baseline": baseline, "n_model": len(mine), "n_baseline": len(base), "paper": claimed,
                      "ours": test.difference, "ci_low": lo, "ci_high": hi, "pair_percentile": pct,
                      "pair_low": pair_lo, "pair_high": pair_hi, "paper_inside_pairs": pair_lo <= claimed <= pair_hi,
                      "_variances": (components(groups).seed_mean_variance(),
                                     components(base_groups).seed_mean_variance())}
            record.update({f"p_{k}": v for k, v in one_sided(mine, base, claimed).items()})
            records.append(record)
    frame = pd.DataFrame(records)
    if not len(frame):
        return pd.DataFrame(columns=COLUMNS)
    for kind in KINDS:
        frame[f"p_{kind}_holm"] = holm(frame[f"p_{kind}"].tolist())
    frame["verdict"] = [decide({k: r[f"p_{k}_holm"] for k in KINDS}, alpha) for _, r in frame.iterrows()]
    frame["explanation"] = [explain(v, bool(i)) for v, i in zip(frame["verdict"], frame["paper_inside_pairs"], strict=True)]
    still_open = max(int((frame["verdict"] == "undecided").sum()), 1)
    frame["seeds_needed"] = [
        seeds_for_difference(r["paper"], *r["_variances"], alpha / still_open, power)
        if r["verdict"] == "undecided" else None for _, r in frame.iterrows()]
    frame["seeds_needed"] = frame["seeds_needed"].astype("Int64")
    return frame.drop(columns="_variances").reindex(columns=COLUMNS)


def _seed_metric_means(rows: pd.DataFrame, model: str, scenarios: list[str]) -> np.ndarray | None:
    """[S, scenarios, 3] seed means of the composite's metrics (in the rows' units: the score
    divides each by its mean, so units cancel), the seeds that have every scenario; None when none."""
    mine = rows[rows["model"] == model]
    cols = list(COMPOSITE)
    means = mine.groupby(["seed", "scenario"])[cols].mean()
    seeds = [s for s in dict.fromkeys(sorted(mine["seed"]))
             if all((s, sc) in means.index for sc in scenarios)]
    if not seeds:
        return None
    return np.stack([[means.loc[(s, sc)].to_numpy(float) for sc in scenarios] for s in seeds])


def ranking_claims(rows: pd.DataFrame, models: list[str], alpha: float = 0.05,
                   n_boot: int = N_BOOT) -> pd.DataFrame:
    """Per scenario of the paper's Table I: the share of whole-seed replicates in which the
    paper's best-scored model ranks first here by composite score (`COLUMNS`)."""
    paper = paper_values()
    scenarios = [s for s in dict.fromkeys(rows["scenario"]) if (s, "CS") in paper.index]
    per_model = {m: _seed_metric_means(rows, m, scenarios) for m in models}
    per_model = {m: v for m, v in per_model.items() if v is not None}
    if len(per_model) < 2 or not scenarios:
        return pd.DataFrame(columns=COLUMNS)
    names = list(per_model)
    rng = bs.rng_for("replication-ranking", *names)
    # [B, models, scenarios, 3]: each replicate's means of whole seeds drawn with replacement
    reps = np.stack([v[rng.integers(0, len(v), (n_boot, len(v)))].mean(axis=1) for v in per_model.values()], axis=1)
    signs = np.array(list(COMPOSITE.values()), float)
    with np.errstate(divide="ignore", invalid="ignore"):
        scores = (reps / reps.mean(axis=1, keepdims=True) * signs).sum(-1)  # [B, models, scenarios]
    first = np.argmax(np.nan_to_num(scores, nan=-np.inf), axis=1)  # [B, scenarios]
    records = []
    for j, scenario in enumerate(scenarios):
        cs = paper.loc[(scenario, "CS"), [m for m in names if m in paper.columns]]
        best = str(cs.idxmax())
        share = float(np.mean(first[:, j] == names.index(best)))
        counts = np.bincount(first[:, j], minlength=len(names))
        verdict = "reproduced" if share >= 1 - alpha else "not reproduced" if share <= alpha else "undecided"
        records.append({"claim": "ranking", "scenario": scenario, "metric": "CS", "model": best,
                        "n_model": len(per_model[best]), "verdict": verdict, "probability_first": share,
                        "most_often_first": names[int(np.argmax(counts))]})
    return pd.DataFrame(records).reindex(columns=COLUMNS)


def replication_table(rows: pd.DataFrame, models: list[str], baseline: str = "M0", alpha: float = 0.05
                      ) -> pd.DataFrame:
    """Every claim the rows can test: the CR_total differences, then the rankings."""
    trimmed = trim_collisions(rows[rows["model"].isin(models)])
    parts = [difference_claims(trimmed, models, baseline, alpha), ranking_claims(trimmed, models, alpha)]
    parts = [p for p in parts if len(p)]
    table = pd.concat(parts, ignore_index=True) if parts else pd.DataFrame(columns=COLUMNS)
    for col in ("n_model", "n_baseline", "seeds_needed"):
        table[col] = table[col].astype("Int64")
    return table


VERDICTS = ("reproduced", "reproduced, smaller", "reproduced, larger", "not reproduced", "reversed", "undecided")


def summary_line(table: pd.DataFrame) -> str:
    """How many claims of each kind end with each verdict, in one sentence a kind."""
    parts = []
    for claim, name in (("difference", "CR_total differences"), ("ranking", "best-score rankings")):
        verdicts = table.loc[table["claim"] == claim, "verdict"]
        if len(verdicts):
            counts = [f"{int((verdicts == v).sum())} {v}" for v in VERDICTS if (verdicts == v).any()]
            parts.append(f"Of the paper's {len(verdicts)} {name}: {'; '.join(counts)}.")
    if not parts:
        return "No claim of the paper to test."
    n = table.loc[table["claim"] == "difference", ["n_model", "n_baseline"]]
    low, high = (int(n.min().min()), int(n.max().max())) if len(n) else (0, 0)
    seeds = (f" ({low} seeds a model)" if low == high else f" ({low}–{high} seeds a model)") if len(n) else ""
    return f"Summary{seeds}. " + " ".join(parts)


def _pct(x: float) -> str:
    return f"{x:.0f}" if math.isfinite(x) else "–"


def replication_markdown(table: pd.DataFrame, alpha: float = 0.05) -> str:
    """The replication table as Markdown, with its rules in the notes."""
    diffs = table[table["claim"] == "difference"]
    ranks = table[table["claim"] == "ranking"]
    lines = [summary_line(table), ""]
    if len(diffs):
        lines += [
            f"Does the paper's ablation reproduce? CR_total, model minus M0, in pp ({len(diffs)} claims, "
            f"Holm-corrected; α = {alpha:g}):",
            "",
            "| Scenario | Model | seeds | paper | ours [95% CI] | paper among our seed pairs | "
            "p direction / reversed / smaller / larger (Holm) | verdict | explanation | seeds needed |",
            "|---|---|---:|---:|---|---|---|---|---|---:|",
        ]
        for _, r in diffs.iterrows():
            where = "inside" if r["paper_inside_pairs"] else "outside"
            ps = " / ".join(p_text(r[f"p_{k}_holm"]) for k in KINDS)
            needed = "–" if pd.isna(r["seeds_needed"]) else str(int(r["seeds_needed"]))
            lines.append(
                f"| {r['scenario']} | {r['model']} | {r['n_model']}/{r['n_baseline']} | {signed(r['paper'], 2)} | "
                f"{signed(r['ours'], 2)} [{signed(r['ci_low'], 2)}, {signed(r['ci_high'], 2)}] | "
                f"percentile {_pct(r['pair_percentile'])}, {where} "
                f"[{signed(r['pair_low'], 2)}, {signed(r['pair_high'], 2)}] | {ps} | {r['verdict']} | {r['explanation']} | {needed} |")
    if len(ranks):
        lines += ["", "The paper's best composite score per scenario, and how often that model ranks first here:", "",
                  "| Scenario | paper's best | seeds | ranks first here | most often first | verdict |",
                  "|---|---|---:|---:|---|---|"]
        for _, r in ranks.iterrows():
            lines.append(f"| {r['scenario']} | {r['model']} | {r['n_model']} | {100 * r['probability_first']:.1f} % | "
                         f"{r['most_often_first']} | {r['verdict']} |")
    lines += [
        "",
        "Collision rates trimmed as the paper's (each evaluation's best and worst simulation dropped). paper: its "
        "Table I difference, one seed a model. ours: the mean of seed means minus M0's, with Welch's interval. "
        "paper among our seed pairs: its percentile among every one-seed-of-the-model minus one-seed-of-M0 "
        "difference of ours (ties half), inside or outside their central 95 % (in brackets); outside, seed luck "
        "does not explain it. p: one-sided permutation tests of the difference of seed means in the paper's "
        "direction: shown in its direction, reversed, smaller than the paper's difference, larger than it; each "
        "kind Holm-adjusted over the claims. verdict: reversed; reproduced, smaller / larger; reproduced "
        "(direction shown); not reproduced (smaller shown, direction not); else undecided, with the seeds per "
        "model that would tell the paper's difference from none at power 0.8 and Holm's level. explanation (claims "
        "that do not reproduce): seed luck where the paper's difference lies inside our pairs' central 95 %, "
        "else not seed luck (whether the paper's rules explain it is the rules study's interaction). Ranking: the "
        "share of whole-seed bootstrap replicates in which the paper's best model has the best composite score "
        f"here; reproduced at ≥ {100 * (1 - alpha):g} %, not reproduced at ≤ {100 * alpha:g} %.",
    ]
    return "\n".join(lines) + "\n"
