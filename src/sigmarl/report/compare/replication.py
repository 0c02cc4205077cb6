"""Does the paper's ablation reproduce? One verdict per claim of its Table I.

The paper trained one seed per model, so each of its differences (Mk - M0, CR_total, per
scenario) is one draw of "one seed of Mk minus one seed of M0". Per claim, from our seed means
(collision rates trimmed as the paper's: each evaluation's best and worst simulation dropped),
every test is the comparison engine's (`sigmarl.stats.engine`: each model resampled from its own
seeds under the null), in the paper's direction s = sign(D): shown in its direction (H0 s d <= 0),
reversed (H0 s d >= 0), smaller than the paper's (H0 s d >= |D|) and larger (H0 s d <= |D|), each
kind Holm-adjusted over the claims; ours d with the engine's interval.

Seed luck: where the paper's D falls among our one-seed-minus-one-seed differences (every pair of
a seed of Mk and a seed of M0): its percentile (ties half) and a two-sided p, twice
(1 + pairs beyond D on its nearer side) / (1 + pairs), Holm-adjusted over the claims.

Verdict, in order: fewer than 2 seeds a side: **undecided**; **reversed** (reversed shown);
**reproduced, smaller** / **reproduced, larger**; **reproduced** (direction shown); **not
reproduced** (smaller shown, direction not); else **undecided**, with the engine's seeds per model
to tell a true difference of D from none at Holm's level for the claims still open. A value that
Table I strikes out (`struck_out` in its csv) is no claim: listed apart, **struck out by the
paper**, with our numbers beside it, outside every family.

Ranking claims: the model with the paper's best composite score on each scenario; the share of
whole-seed bootstrap replicates (each model's seeds drawn with replacement, a drawn seed bringing
all its scenarios; composite normalisers recomputed per replicate) in which that model ranks first
here; reproduced at >= 1 - alpha, not reproduced at <= alpha, else (or with fewer than 2 seeds of a
model) undecided.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pandas as pd

from sigmarl.metrics import COMPOSITE, CR_TOTAL, CS
from sigmarl.report.cells import trim_collisions
from sigmarl.report.compare.verdicts import Design, interaction_table, seed_values
from sigmarl.report.tables import p_text, paper_values, signed, struck_out
from sigmarl.stats import bootstrap as bs
from sigmarl.stats.engine import Null, difference, holm, seeds_needed

# A claim of the replication table (Mk - M0) beside the study's interaction on it: Mk - M0 under
# another condition (x against its own baseline) against ours (y = Mk against M0), CR_total.
CLAIM_COLUMNS = ["interaction", "interaction_seeds", "interaction_difference", "interaction_ci_low",
                 "interaction_ci_high", "p_interaction", "interaction_verdict"]
PAPERS_WAY, AGAINST = "paper's direction", "against the paper's direction"


def claim_interactions(trimmed: pd.DataFrame, design: Design, claims: pd.DataFrame, baseline: str) -> pd.DataFrame:
    """`CLAIM_COLUMNS` per row of `claims` (the replication table's), from the design's
    interactions whose y is the claim's model compared with `baseline`, on CR_total per scenario
    (the engine's test over their own Holm family). The verdict: **paper's direction** where a zero
    interaction is rejected and it moves Mk - M0 the way the paper's difference lies, **against
    the paper's direction** where it is rejected the other way, **same** within the margin, else
    **undecided** (always with one seed in a group). Empty where the claim has no interaction."""
    chosen = {name: (x, y) for name, (x, y) in design.interactions.items() if design.baseline_of(y) == baseline}
    out = pd.DataFrame(index=claims.index, columns=CLAIM_COLUMNS)
    if not chosen:
        return out
    table = interaction_table(trimmed, replace(design, interactions=chosen, metrics=(METRIC,), scenarios=None))
    by_claim = {(r["scenario"], chosen[r["interaction"]][1]): r for _, r in table.iterrows()}
    groups = trimmed.groupby("model")["seed"].nunique()
    for i, claim in claims.iterrows():
        r = by_claim.get((claim["scenario"], claim["model"]))
        if r is None or claim["claim"] != "difference":
            continue
        x, y = chosen[r["interaction"]]
        seeds = "/".join(str(int(groups.get(m, 0))) for m in (x, design.baseline_of(x), y, design.baseline_of(y)))
        way = r["difference"] * claim["paper"] > 0
        verdict = (PAPERS_WAY if way else AGAINST) if r["verdict"] == "differs" else r["verdict"]
        out.loc[i] = [x, seeds, r["difference"], r["ci_low"], r["ci_high"], r["p_difference_holm"], verdict]
    return out


def claim_interactions_lines(table: pd.DataFrame) -> list[str]:
    """The claims that have an interaction, as a Markdown table (none: no lines)."""
    rows = table[table["interaction_verdict"].notna() & (table["interaction_verdict"] != "")]
    if not len(rows):
        return []
    lines = ["", "Does the other condition explain a claim? Its Mk − M0 against ours (x: the condition's column; "
             f"difference of differences, CR_total in pp, the comparison engine, {len(rows)} tests Holm-corrected):",
             "", "| Scenario | Model | x | seeds x / its M0 / Mk / M0 | paper | difference of differences [95% CI] "
             "| p (Holm) | verdict |", "|---|---|---|---|---:|---|---:|---|"]
    for _, r in rows.iterrows():
        lines.append(f"| {r['scenario']} | {r['model']} | {r['interaction']} | {r['interaction_seeds']} | "
                     f"{signed(r['paper'], 2)} | {signed(r['interaction_difference'], 2)} "
                     f"[{signed(r['interaction_ci_low'], 2)}, {signed(r['interaction_ci_high'], 2)}] | "
                     f"{p_text(r['p_interaction'])} | {r['interaction_verdict']} |")
    lines += ["", "paper's direction: a zero interaction rejected at Holm's level, the condition moving Mk − M0 the "
              "way the paper's difference lies (then a claim that does not reproduce is explained by it, "
              "paper_policies.md); against the paper's direction: rejected the other way; same: within the margin by "
              "two one-sided tests; else undecided (always with one seed in a group)."]
    return lines


METRIC = CR_TOTAL
N_BOOT = 2000
STRUCK = "struck out by the paper"
COLUMNS = [
    "claim", "scenario", "model", "seeds", "paper", "ours", "ci_low", "ci_high", "pair_percentile",
    "p_seed_luck", "p_direction", "p_reversed", "p_smaller", "p_larger", "verdict", "explanation",
    "seeds_needed", *CLAIM_COLUMNS,
]  # fmt: skip
KINDS = ("direction", "reversed", "smaller", "larger")


def pair_position(mine: np.ndarray, base: np.ndarray, paper: float) -> tuple[float, float]:
    """The paper's difference among every one-seed-minus-one-seed difference of our seed means:
    its percentile (ties half) and its two-sided p, 2 (1 + pairs beyond it on its nearer side)
    / (1 + pairs), capped at 1 (the chance that one more pair lies as far out)."""
    pairs = (mine[:, None] - base[None, :]).ravel()
    below, tied = np.count_nonzero(pairs < paper), np.count_nonzero(pairs == paper)
    above = len(pairs) - below - tied
    p = min(1.0, 2 * (1 + min(below, above) + 0.5 * tied) / (1 + len(pairs)))
    return 100.0 * (below + 0.5 * tied) / len(pairs), p


def one_sided(mine: np.ndarray, base: np.ndarray, paper: float):
    """The engine's record of a claim, with its four one-sided p-values in the paper's direction."""
    s = 1.0 if paper >= 0 else -1.0
    size = abs(paper)
    nulls = {"direction": Null(0.0, "greater"), "reversed": Null(0.0, "less"),
             "smaller": Null(size, "less"), "larger": Null(size, "greater")}
    record = difference(s * mine, s * base, nulls)
    return record, s


def decide(p: dict[str, float], alpha: float) -> str:
    """The verdict of one claim from its Holm-adjusted p-values (`KINDS`)."""
    if p["reversed"] <= alpha:
        return "reversed"
    if p["direction"] <= alpha:
        if p["smaller"] <= alpha:
            return "reproduced, smaller"
        return "reproduced, larger" if p["larger"] <= alpha else "reproduced"
    return "not reproduced" if p["smaller"] <= alpha else "undecided"


def explain(verdict: str, p_luck: float, p_luck_holm: float, alpha: float) -> str:
    """What a claim that does not reproduce is attributed to from this study's seeds alone: seed
    luck where the paper's one-seed difference is not rare among our pairs; rare under seed luck
    where it is at alpha but not at Holm's level over the claims; else not seed luck (whether the
    paper's rules explain it is the rules study's interaction, not this table's)."""
    if verdict.startswith("reproduced") or verdict == STRUCK or not math.isfinite(p_luck):
        return "–"
    if p_luck_holm <= alpha:
        return "not seed luck"
    return "rare under seed luck" if p_luck <= alpha else "seed luck"


def _claim(scenario: str, model: str, claimed: float, groups, base_groups) -> dict:
    mine = np.array([g.mean() for g in groups])
    base = np.array([g.mean() for g in base_groups])
    record, s = one_sided(mine, base, claimed)
    lo, hi = (s * record.ci_low, s * record.ci_high) if s > 0 else (s * record.ci_high, s * record.ci_low)
    pct, p_luck = pair_position(mine, base, claimed)
    return {"claim": "difference", "scenario": scenario, "model": model, "seeds": f"{len(mine)}/{len(base)}",
            "paper": claimed, "ours": s * record.estimate, "ci_low": lo, "ci_high": hi, "pair_percentile": pct,
            "_p_luck": p_luck if record.decidable else math.nan, "_n": min(len(mine), len(base)),
            "_variances": (float(np.var(mine, ddof=1)) if len(mine) > 1 else math.nan,
                           float(np.var(base, ddof=1)) if len(base) > 1 else math.nan),
            **{f"p_{k}": v for k, v in record.p.items()}}


def difference_claims(rows: pd.DataFrame, models: list[str], baseline: str, alpha: float = 0.05,
                      power: float = 0.8) -> pd.DataFrame:
    """One row per (scenario, model) claim of the paper's CR_total differences (`COLUMNS`), the
    values Table I strikes out after them."""
    paper, struck = paper_values(), struck_out()
    values = seed_values(rows, METRIC)
    records = []
    for scenario in dict.fromkeys(rows["scenario"]):
        for model in models:
            key = (scenario, METRIC)
            if model == baseline or key not in paper.index or model not in paper.columns:
                continue
            groups, base_groups = values.get((model, scenario)), values.get((baseline, scenario))
            if not groups or not base_groups:
                continue
            claimed = float(paper.loc[key, model] - paper.loc[key, baseline])
            record = _claim(scenario, model, claimed, groups, base_groups)
            record["_struck"] = (scenario, METRIC, model) in struck
            records.append(record)
    if not records:
        return pd.DataFrame(columns=COLUMNS)
    frame = pd.DataFrame(records)
    claims = frame[~frame["_struck"]].copy()
    for kind in KINDS:
        claims[f"p_{kind}"] = holm(claims[f"p_{kind}"].tolist())
    claims["p_seed_luck"] = holm(claims["_p_luck"].tolist())
    claims["verdict"] = [decide({k: r[f"p_{k}"] for k in KINDS}, alpha) for _, r in claims.iterrows()]
    claims["explanation"] = [explain(r["verdict"], r["_p_luck"], r["p_seed_luck"], alpha) for _, r in claims.iterrows()]
    still_open = max(int((claims["verdict"] == "undecided").sum()), 1)
    claims["seeds_needed"] = [
        seeds_needed(r["paper"], r["_variances"], (1.0, -1.0), alpha / still_open, power, sides=1)
        if r["verdict"] == "undecided" and r["_n"] >= 2 else None for _, r in claims.iterrows()]
    gone = frame[frame["_struck"]].copy()
    gone[[f"p_{k}" for k in KINDS]] = math.nan
    gone = gone.assign(p_seed_luck=math.nan, verdict=STRUCK, explanation="–", seeds_needed=None)
    return pd.concat([claims, gone], ignore_index=True).reindex(columns=COLUMNS)


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
    scenarios = [s for s in dict.fromkeys(rows["scenario"]) if (s, CS) in paper.index]
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
        cs = paper.loc[(scenario, CS), [m for m in names if m in paper.columns]]
        best = str(cs.idxmax())
        share = float(np.mean(first[:, j] == names.index(best)))
        counts = np.bincount(first[:, j], minlength=len(names))
        verdict = "reproduced" if share >= 1 - alpha else "not reproduced" if share <= alpha else "undecided"
        if min(len(v) for v in per_model.values()) < 2:  # one seed ranks by luck alone
            verdict = "undecided"
        records.append({"claim": "ranking", "scenario": scenario, "model": best,
                        "seeds": str(len(per_model[best])), "ours": share, "verdict": verdict,
                        "explanation": f"most often first: {names[int(np.argmax(counts))]}"})
    return pd.DataFrame(records).reindex(columns=COLUMNS)


def replication_table(rows: pd.DataFrame, models: list[str], baseline: str = "M0", alpha: float = 0.05,
                      design: Design | None = None) -> pd.DataFrame:
    """Every claim the rows can test: the CR_total differences, then the rankings; beside each
    difference, the `design`'s interaction on it where it declares one over the rows' columns
    (`claim_interactions`)."""
    trimmed = trim_collisions(rows[rows["model"].isin(models)])
    parts = [difference_claims(trimmed, models, baseline, alpha), ranking_claims(trimmed, models, alpha)]
    parts = [p for p in parts if len(p)]
    table = pd.concat(parts, ignore_index=True).reindex(columns=COLUMNS) if parts else pd.DataFrame(columns=COLUMNS)
    table["seeds_needed"] = table["seeds_needed"].astype("Int64")
    if design is not None and len(table):
        table[CLAIM_COLUMNS] = claim_interactions(trim_collisions(rows), replace(design, alpha=alpha), table, baseline)
    return table


VERDICTS = ("reproduced", "reproduced, smaller", "reproduced, larger", "not reproduced", "reversed", "undecided")


def summary_line(table: pd.DataFrame) -> str:
    """How many claims of each kind end with each verdict, in one sentence a kind (the values
    Table I strikes out counted apart)."""
    parts = []
    for claim, name in (("difference", "CR_total differences"), ("ranking", "best-score rankings")):
        verdicts = table.loc[table["claim"] == claim, "verdict"]
        struck = int((verdicts == STRUCK).sum())
        verdicts = verdicts[verdicts != STRUCK]
        if len(verdicts):
            counts = [f"{int((verdicts == v).sum())} {v}" for v in VERDICTS if (verdicts == v).any()]
            apart = f" ({struck} more {STRUCK})" if struck else ""
            parts.append(f"Of the paper's {len(verdicts)} {name}{apart}: {'; '.join(counts)}.")
    if not parts:
        return "No claim of the paper to test."
    n = table.loc[table["claim"] == "difference", "seeds"].str.split("/", expand=True).astype(int) \
        if (table["claim"] == "difference").any() else pd.DataFrame()
    low, high = (int(n.min().min()), int(n.max().max())) if len(n) else (0, 0)
    seeds = (f" ({low} seeds a model)" if low == high else f" ({low}–{high} seeds a model)") if len(n) else ""
    return f"Summary{seeds}. " + " ".join(parts)


def _pct(x: float) -> str:
    return f"{x:.0f}" if math.isfinite(x) else "–"


def _interval(r: pd.Series) -> str:
    if not math.isfinite(r["ci_low"]):
        return f"{signed(r['ours'], 2)} [–]"
    return f"{signed(r['ours'], 2)} [{signed(r['ci_low'], 2)}, {signed(r['ci_high'], 2)}]"


def _difference_lines(diffs: pd.DataFrame, alpha: float) -> list[str]:
    claims, struck = diffs[diffs["verdict"] != STRUCK], diffs[diffs["verdict"] == STRUCK]
    lines = [
        f"Does the paper's ablation reproduce? CR_total, model minus M0, in pp ({len(claims)} claims, "
        f"Holm-corrected; α = {alpha:g}):",
        "",
        "| Scenario | Model | seeds | paper | ours [95% CI] | paper among our seed pairs: percentile, p (Holm) | "
        "p direction / reversed / smaller / larger (Holm) | verdict | explanation | seeds needed |",
        "|---|---|---:|---:|---|---|---|---|---|---:|",
    ]
    for _, r in claims.iterrows():
        ps = " / ".join(p_text(r[f"p_{k}"]) for k in KINDS)
        needed = "–" if pd.isna(r["seeds_needed"]) else str(int(r["seeds_needed"]))
        lines.append(
            f"| {r['scenario']} | {r['model']} | {r['seeds']} | {signed(r['paper'], 2)} | {_interval(r)} | "
            f"{_pct(r['pair_percentile'])}, {p_text(r['p_seed_luck'])} | {ps} | {r['verdict']} | {r['explanation']} "
            f"| {needed} |")
    if len(struck):
        lines += ["", f"Values Table I strikes out ({STRUCK}; no claim, in no family), ours beside them:", "",
                  "| Scenario | Model | seeds | paper | ours [95% CI] |", "|---|---|---:|---:|---|"]
        lines += [f"| {r['scenario']} | {r['model']} | {r['seeds']} | {signed(r['paper'], 2)} | {_interval(r)} |"
                  for _, r in struck.iterrows()]
    return lines


def replication_markdown(table: pd.DataFrame, alpha: float = 0.05) -> str:
    """The replication table as Markdown, with its rules in the notes."""
    diffs = table[table["claim"] == "difference"]
    ranks = table[table["claim"] == "ranking"]
    lines = [summary_line(table), ""]
    if len(diffs):
        lines += _difference_lines(diffs, alpha)
        if "interaction_verdict" in diffs:
            lines += claim_interactions_lines(diffs)
    if len(ranks):
        lines += ["", "The paper's best composite score per scenario, and how often that model ranks first here:", "",
                  "| Scenario | paper's best | seeds | ranks first here | most often first | verdict |",
                  "|---|---|---:|---:|---|---|"]
        for _, r in ranks.iterrows():
            lines.append(f"| {r['scenario']} | {r['model']} | {r['seeds']} | {100 * r['ours']:.1f} % | "
                         f"{r['explanation'].removeprefix('most often first: ')} | {r['verdict']} |")
    lines += [
        "",
        "Collision rates trimmed as the paper's (each evaluation's best and worst simulation dropped). paper: its "
        "Table I difference, one seed a model. ours: the mean of seed means minus M0's, with the comparison "
        "engine's bootstrap-t interval (– with one seed). paper among our seed pairs: its percentile among every "
        "one-seed-of-the-model minus one-seed-of-M0 difference of ours (ties half) and the two-sided p of one "
        "more pair lying as far out, Holm-adjusted over the claims. p: the comparison engine's one-sided tests "
        "(each model resampled from its own seeds under the null, docs/concepts.md) in the paper's direction: "
        "shown in its direction, reversed, smaller than the paper's difference, larger than it; each kind "
        "Holm-adjusted over the claims. verdict: reversed; reproduced, smaller / larger; reproduced (direction "
        "shown); not reproduced (smaller shown, direction not); else undecided (always with fewer than 2 seeds a "
        "side), with the seeds per model at which the engine's rule (Welch's t, one-sided, Holm's level over the "
        "claims still open) shows the paper's difference with power 0.8. explanation (claims that do not "
        f"reproduce): not seed luck where the pairs' Holm-adjusted p is ≤ {alpha:g}; rare under seed luck where only "
        f"the unadjusted one is; else seed luck (whether the paper's rules explain it is the rules study's "
        "interaction). Ranking: the share of whole-seed bootstrap replicates in which the paper's best model has "
        f"the best composite score here; reproduced at ≥ {100 * (1 - alpha):g} %, not reproduced at ≤ "
        f"{100 * alpha:g} %, undecided with one seed of a model.",
    ]
    return "\n".join(lines) + "\n"
