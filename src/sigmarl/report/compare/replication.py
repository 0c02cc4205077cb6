"""Does the paper's ablation reproduce? One verdict per claim of its Table I: each Mk - M0 of
CR_total per scenario (`difference_claims`), each scenario's best composite score
(`ranking_claims`), and the study's interaction on a claim (`claim_interactions`); the notes under
`replication_markdown`'s tables state every rule.

The paper trained one seed per model, so each of its differences D is one draw of "one seed of Mk
minus one seed of M0": tested against our seed means (collision rates trimmed as the paper's) by
the comparison engine in the paper's direction s = sign(D), four ways (`one_sided`), and located
among our one-seed-minus-one-seed differences (`pair_position`: was D seed luck?).
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import NamedTuple

import numpy as np
import pandas as pd

from sigmarl.metrics import COMPOSITE, CR_TOTAL, CS
from sigmarl.report.cells import trim_collisions
from sigmarl.report.compare.verdicts import Design, interaction_table, seed_means
from sigmarl.report.tables import (
    interval_signed,
    markdown_table,
    p_text,
    paper_values,
    signed,
    struck_out,
)
from sigmarl.stats import bootstrap as bs
from sigmarl.stats.engine import Null, difference, holm, seeds_needed

METRIC = CR_TOTAL
N_BOOT = 2000
STRUCK = "struck out by the paper"
PAPERS_WAY, AGAINST = "paper's direction", "against the paper's direction"
KINDS = ("direction", "reversed", "smaller", "larger")
P_KINDS = [f"p_{k}" for k in KINDS]
# the tests a verdict rests on: its `p_verdict` is the largest of their Holm-adjusted p-values
DECIDED_BY = {"reversed": ("reversed",), "reproduced": ("direction",), "reproduced, smaller": ("direction", "smaller"),
              "reproduced, larger": ("direction", "larger"), "not reproduced": ("smaller",),
              "undecided": ("direction",)}
# replication.csv; the table in memory holds each kind's Holm-adjusted p after them (p_direction, ...)
COLUMNS = ["scenario", "model", "seeds", "paper", "ours", "ci_low", "ci_high", "pair_percentile", "p_seed_luck",
           "p_verdict", "verdict", "explanation", "seeds_needed"]
RANKING_COLUMNS = ["scenario", "paper_best", "seeds", "share_first", "most_often_first", "verdict"]
# a claim's Mk - M0 under another condition (the `condition` column against its own baseline) set
# against ours, CR_total per scenario
INTERACTION_COLUMNS = ["scenario", "model", "condition", "seeds", "paper", "difference", "ci_low", "ci_high",
                       "p_difference_holm", "verdict"]


class Replication(NamedTuple):
    differences: pd.DataFrame  # `COLUMNS`, then p_<kind> per `KINDS`
    rankings: pd.DataFrame  # `RANKING_COLUMNS`
    interactions: pd.DataFrame  # `INTERACTION_COLUMNS`


def claim_interactions(trimmed: pd.DataFrame, design: Design, claims: pd.DataFrame, baseline: str) -> pd.DataFrame:
    """Per difference claim that has one, the design's interaction whose y is the claim's model
    compared with `baseline` (`INTERACTION_COLUMNS`; the engine's test, `interaction_table`, over
    their own Holm family). The verdict: **paper's direction** where a zero interaction is rejected
    and it moves Mk - M0 the way the paper's difference lies, **against the paper's direction**
    where it is rejected the other way, else the interaction's own (same, undecided)."""
    chosen = {name: (x, y) for name, (x, y) in design.interactions.items() if design.baseline_of(y) == baseline}
    if not chosen or not len(claims):
        return pd.DataFrame(columns=INTERACTION_COLUMNS)
    table = interaction_table(trimmed, replace(design, interactions=chosen, metrics=(METRIC,), scenarios=None))
    table = table.assign(model=[chosen[n][1] for n in table["interaction"]],
                         condition=[chosen[n][0] for n in table["interaction"]])
    table = claims[["scenario", "model", "paper"]].merge(table, on=["scenario", "model"])
    way = np.where(table["difference"] * table["paper"] > 0, PAPERS_WAY, AGAINST)
    table["verdict"] = np.where(table["verdict"] == "differs", way, table["verdict"])
    return table[INTERACTION_COLUMNS]


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
    """The engine's record of a claim and s = sign(D): its one-sided tests of our difference d in
    the paper's direction, shown in it (H0 s d <= 0), reversed (s d >= 0), smaller than the
    paper's (s d >= |D|), larger (s d <= |D|)."""
    s, size = (1.0 if paper >= 0 else -1.0), abs(paper)
    nulls = {"direction": Null(0.0, "greater"), "reversed": Null(0.0, "less"),
             "smaller": Null(size, "less"), "larger": Null(size, "greater")}
    return difference(s * mine, s * base, nulls), s


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


def _claim(scenario: str, model: str, claimed: float, mine: np.ndarray, base: np.ndarray) -> dict:
    record, s = one_sided(mine, base, claimed)
    lo, hi = (s * record.ci_low, s * record.ci_high) if s > 0 else (s * record.ci_high, s * record.ci_low)
    pct, p_luck = pair_position(mine, base, claimed)
    return {"scenario": scenario, "model": model, "seeds": f"{len(mine)}/{len(base)}",
            "paper": claimed, "ours": s * record.estimate, "ci_low": lo, "ci_high": hi, "pair_percentile": pct,
            "_p_luck": p_luck if record.decidable else math.nan, "_n": min(len(mine), len(base)),
            "_variances": (float(np.var(mine, ddof=1)) if len(mine) > 1 else math.nan,
                           float(np.var(base, ddof=1)) if len(base) > 1 else math.nan),
            **{f"p_{k}": v for k, v in record.p.items()}}


def difference_claims(rows: pd.DataFrame, models: list[str], baseline: str, alpha: float = 0.05,
                      power: float = 0.8) -> pd.DataFrame:
    """One row per (scenario, model) claim of the paper's CR_total differences (`COLUMNS`, then
    `P_KINDS`), the values Table I strikes out after them."""
    paper, struck = paper_values(), struck_out()
    values = seed_means(rows, METRIC)
    records = []
    for scenario in dict.fromkeys(rows["scenario"]):
        for model in models:
            key = (scenario, METRIC)
            if model == baseline or key not in paper.index or model not in paper.columns:
                continue
            mine, base = values.get((model, scenario)), values.get((baseline, scenario))
            if mine is None or base is None:
                continue
            record = _claim(scenario, model, float(paper.loc[key, model] - paper.loc[key, baseline]), mine, base)
            record["_struck"] = (scenario, METRIC, model) in struck
            records.append(record)
    if not records:
        return pd.DataFrame(columns=[*COLUMNS, *P_KINDS])
    frame = pd.DataFrame(records)
    claims = frame[~frame["_struck"]].copy()
    for kind in P_KINDS:
        claims[kind] = holm(claims[kind].tolist())
    claims["p_seed_luck"] = holm(claims["_p_luck"].tolist())
    claims["verdict"] = [decide({k: r[f"p_{k}"] for k in KINDS}, alpha) for _, r in claims.iterrows()]
    claims["p_verdict"] = [max(r[f"p_{k}"] for k in DECIDED_BY[r["verdict"]]) for _, r in claims.iterrows()]
    claims["explanation"] = [explain(r["verdict"], r["_p_luck"], r["p_seed_luck"], alpha) for _, r in claims.iterrows()]
    still_open = max(int((claims["verdict"] == "undecided").sum()), 1)
    claims["seeds_needed"] = [
        seeds_needed(r["paper"], r["_variances"], (1.0, -1.0), alpha / still_open, power, sides=1)
        if r["verdict"] == "undecided" and r["_n"] >= 2 else None for _, r in claims.iterrows()]
    gone = frame[frame["_struck"]].copy()
    gone[P_KINDS] = math.nan
    gone = gone.assign(p_seed_luck=math.nan, p_verdict=math.nan, verdict=STRUCK, explanation="–", seeds_needed=None)
    table = pd.concat([claims, gone], ignore_index=True).reindex(columns=[*COLUMNS, *P_KINDS])
    table["seeds_needed"] = table["seeds_needed"].astype("Int64")
    return table


def _seed_metric_means(rows: pd.DataFrame, model: str, scenarios: list[str]) -> np.ndarray | None:
    """[S, scenarios, 3] seed means of the composite's metrics (in the rows' units: the score
    divides each by its mean, so units cancel), the seeds that have every scenario; None when none."""
    mine = rows[rows["model"] == model]
    means = mine.groupby(["seed", "scenario"])[list(COMPOSITE)].mean()
    seeds = [s for s in dict.fromkeys(sorted(mine["seed"])) if all((s, sc) in means.index for sc in scenarios)]
    if not seeds:
        return None
    return np.stack([[means.loc[(s, sc)].to_numpy(float) for sc in scenarios] for s in seeds])


def ranking_claims(rows: pd.DataFrame, models: list[str], alpha: float = 0.05,
                   n_boot: int = N_BOOT) -> pd.DataFrame:
    """Per scenario of the paper's Table I (`RANKING_COLUMNS`): the share of whole-seed bootstrap
    replicates (each model's seeds drawn with replacement, a drawn seed bringing all its scenarios,
    the composite's normalisers recomputed per replicate) in which the paper's best-scored model
    ranks first here; reproduced at >= 1 - alpha, not reproduced at <= alpha, else (or with one
    seed of a model) undecided."""
    paper = paper_values()
    scenarios = [s for s in dict.fromkeys(rows["scenario"]) if (s, CS) in paper.index]
    per_model = {m: _seed_metric_means(rows, m, scenarios) for m in models}
    per_model = {m: v for m, v in per_model.items() if v is not None}
    if len(per_model) < 2 or not scenarios:
        return pd.DataFrame(columns=RANKING_COLUMNS)
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
        best = str(paper.loc[(scenario, CS), [m for m in names if m in paper.columns]].idxmax())
        share = float(np.mean(first[:, j] == names.index(best)))
        verdict = "reproduced" if share >= 1 - alpha else "not reproduced" if share <= alpha else "undecided"
        if min(len(v) for v in per_model.values()) < 2:  # one seed ranks by luck alone
            verdict = "undecided"
        records.append({"scenario": scenario, "paper_best": best, "seeds": len(per_model[best]), "share_first": share,
                        "most_often_first": names[int(np.argmax(np.bincount(first[:, j], minlength=len(names))))],
                        "verdict": verdict})
    return pd.DataFrame(records, columns=RANKING_COLUMNS)


def replication_table(rows: pd.DataFrame, models: list[str], baseline: str = "M0", alpha: float = 0.05,
                      design: Design | None = None) -> Replication:
    """Every claim the rows can test: the CR_total differences, the rankings and, where the
    `design` declares one over the rows' columns, the interaction on a difference."""
    trimmed = trim_collisions(rows[rows["model"].isin(models)])
    diffs = difference_claims(trimmed, models, baseline, alpha)
    interactions = pd.DataFrame(columns=INTERACTION_COLUMNS) if design is None else \
        claim_interactions(trim_collisions(rows), replace(design, alpha=alpha), diffs, baseline)
    return Replication(diffs, ranking_claims(trimmed, models, alpha), interactions)


VERDICTS = ("reproduced", "reproduced, smaller", "reproduced, larger", "not reproduced", "reversed", "undecided")


def summary_line(differences: pd.DataFrame, rankings: pd.DataFrame) -> str:
    """How many claims of each kind end with each verdict, in one sentence a kind (the values
    Table I strikes out counted apart)."""
    parts = []
    for verdicts, name in ((differences["verdict"], "CR_total differences"), (rankings["verdict"], "best-score rankings")):
        struck = int((verdicts == STRUCK).sum())
        verdicts = verdicts[verdicts != STRUCK]
        if len(verdicts):
            counts = [f"{int((verdicts == v).sum())} {v}" for v in VERDICTS if (verdicts == v).any()]
            apart = f" ({struck} more {STRUCK})" if struck else ""
            parts.append(f"Of the paper's {len(verdicts)} {name}{apart}: {'; '.join(counts)}.")
    if not parts:
        return "No claim of the paper to test."
    n = differences["seeds"].str.split("/").explode().astype(int)  # every model's seeds
    span = f"{n.min()} seed" if n.max() == 1 else f"{n.min()} seeds" if n.min() == n.max() else f"{n.min()}–{n.max()} seeds"
    return "Summary" + (f" ({span} a model)" if len(n) else "") + ". " + " ".join(parts)


def _ours(r: dict) -> str:
    if not math.isfinite(r["ci_low"]):
        return f"{signed(r['ours'], 2)} [–]"
    return interval_signed(r["ours"], r["ci_low"], r["ci_high"], 2)


def _difference_lines(diffs: pd.DataFrame, alpha: float) -> list[str]:
    claims, struck = diffs[diffs["verdict"] != STRUCK], diffs[diffs["verdict"] == STRUCK]
    first = {"Scenario": "scenario", "Model": "model", "seeds": "seeds", "paper": lambda r: signed(r["paper"], 2),
             "ours [95% CI]": _ours}
    lines = [f"Does the paper's ablation reproduce? CR_total, model minus M0, in pp ({len(claims)} claims, "
             f"Holm-corrected; α = {alpha:g}):", "", *markdown_table(claims, {
                 **first, "paper among our seed pairs: percentile, p (Holm)":
                     lambda r: f"{r['pair_percentile']:.0f}, {p_text(r['p_seed_luck'])}",
                 "p direction / reversed / smaller / larger (Holm)": lambda r: " / ".join(p_text(r[k]) for k in P_KINDS),
                 "verdict": "verdict", "explanation": "explanation",
                 "seeds needed": lambda r: "–" if pd.isna(r["seeds_needed"]) else str(int(r["seeds_needed"]))},
                 "llrrlllllr")]
    if len(struck):
        lines += ["", f"Values Table I strikes out ({STRUCK}; no claim, in no family), ours beside them:", "",
                  *markdown_table(struck, first, "llrrl")]
    return lines


def _interaction_lines(table: pd.DataFrame) -> list[str]:
    """The claims that have an interaction, as a Markdown table (none: no lines)."""
    if not len(table):
        return []
    return ["", "Does the other condition explain a claim? Its Mk − M0 against ours (x: the condition's column; "
            f"difference of differences, CR_total in pp, the comparison engine, {len(table)} tests Holm-corrected):",
            "", *markdown_table(table, {
                "Scenario": "scenario", "Model": "model", "x": "condition", "seeds x / its M0 / Mk / M0": "seeds",
                "paper": lambda r: signed(r["paper"], 2), "difference of differences [95% CI]":
                    lambda r: interval_signed(r["difference"], r["ci_low"], r["ci_high"], 2),
                "p (Holm)": lambda r: p_text(r["p_difference_holm"]), "verdict": "verdict"}, "llllrlrl"),
            "", "paper's direction: a zero interaction rejected at Holm's level, the condition moving Mk − M0 the "
            "way the paper's difference lies (then a claim that does not reproduce is explained by it, "
            "paper_policies.md); against the paper's direction: rejected the other way; same: within the margin by "
            "two one-sided tests; else undecided (always with one seed in a group)."]


def replication_markdown(replication: Replication, alpha: float = 0.05) -> str:
    """The replication tables as Markdown, with their rules in the notes."""
    diffs, ranks, interactions = replication
    lines = [summary_line(diffs, ranks), ""]
    if len(diffs):
        lines += _difference_lines(diffs, alpha) + _interaction_lines(interactions)
    if len(ranks):
        lines += ["", "The paper's best composite score per scenario, and how often that model ranks first here:", "",
                  *markdown_table(ranks, {"Scenario": "scenario", "paper's best": "paper_best", "seeds": "seeds",
                                          "ranks first here": lambda r: f"{100 * r['share_first']:.1f} %",
                                          "most often first": "most_often_first", "verdict": "verdict"}, "llrrll")]
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
