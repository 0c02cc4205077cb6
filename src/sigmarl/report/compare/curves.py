"""Training curves compared. When does a difference appear? Per declared comparison and window of
`WINDOW` iterations, the engine's two-sided test on the seeds' mean episode reward over the window,
Holm-corrected over every (comparison, window); a comparison *parts* at the first window from
which every later window is decided the same way. Is the paper's curve one of ours? Its final
reward is one seed's; ours give the prediction interval for one more seed's final reward (mean of
the last `training.LAST` iterations), mean +- t s sqrt(1 + 1/n). Rewards of variants trained under
different rules are not measured alike (the paper's rules add a lagged steering penalty and
terminal time-outs), nor logged alike: the paper's collector counts episodes whole across batch
ends, ours counts the cut segment as an episode, 0.5-0.6 lower (docs/deviations.md); a variant
whose every seed logged the estimate of the paper's definition (`episode_reward_mean_complete`)
is compared on it ("complete"), older runs on ours ("batch-cut").
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from sigmarl.report.compare.verdicts import Design
from sigmarl.report.tables import markdown_table, signed
from sigmarl.report.training import LAST
from sigmarl.stats.bootstrap import t_critical
from sigmarl.stats.engine import Null, difference, holm

WINDOW = 25  # iterations per window: the curves are noisy per iteration

SEPARATION_COLUMNS = ["model", "baseline", "first", "last", "seeds", "difference", "ci_low", "ci_high",
                      "p_difference", "p_difference_holm", "verdict"]


PAPER_SEED_COLUMNS = ["variant", "paper_model", "reward", "seeds", "mean", "pi_low", "pi_high", "paper", "verdict"]
# what our side of the paper-seed comparison reads: the paper's definition, estimated, or our own
COMPLETE, CUT = "complete", "batch-cut"


def window_means(curves: pd.DataFrame, window: int = WINDOW) -> pd.DataFrame:
    """Each (model, seed)'s mean reward per window of `window` iterations (1..window, ...):
    columns model, seed, first, last, reward. A window the run has not finished is left out."""
    c = curves.assign(model=curves["model"].astype(str))
    if "seed" not in c.columns:
        c = c.assign(seed=0)
    c = c.assign(first=(c["iteration"] - 1) // window * window + 1)
    g = c.groupby(["model", "seed", "first"], sort=True)["reward"]
    out = g.mean().rename("reward").reset_index()
    out = out[g.size().to_numpy() == window]
    return out.assign(last=out["first"] + window - 1)[["model", "seed", "first", "last", "reward"]]


def separation_table(curves: pd.DataFrame, design: Design, window: int = WINDOW) -> pd.DataFrame:
    """Per compared variant and window its difference in mean reward from its baseline, with
    the engine's interval and verdict (higher, lower or undecided at Holm's level over all rows)."""
    means = window_means(curves, window)
    rows = []
    for variant in design.compared:
        base = design.baseline_of(variant)
        a, b = means[means["model"] == variant], means[means["model"] == base]
        for first in sorted(set(a["first"]) & set(b["first"])):
            x = a.loc[a["first"] == first, "reward"].to_numpy()
            y = b.loc[b["first"] == first, "reward"].to_numpy()
            r = difference(x, y, {"zero": Null(0.0)}, 1 - design.alpha)
            rows.append({"model": variant, "baseline": base, "first": int(first), "last": int(first + window - 1),
                         "seeds": f"{len(x)}/{len(y)}", "difference": r.estimate, "ci_low": r.ci_low,
                         "ci_high": r.ci_high, "p_difference": r.p["zero"]})
    frame = pd.DataFrame(rows, columns=SEPARATION_COLUMNS)
    frame["p_difference_holm"] = holm(frame["p_difference"].to_numpy()) if len(frame) else []
    decided = np.nan_to_num(frame["p_difference_holm"].to_numpy(float), nan=1.0) <= design.alpha
    frame["verdict"] = np.where(decided, np.where(frame["difference"] > 0, "higher", "lower"), "undecided")
    return frame


def parting(table: pd.DataFrame) -> dict[tuple[str, str], tuple[int, str] | None]:
    """(variant, baseline) -> (first iteration of the window from which every later window has
    the same decided verdict, that verdict), or None where the last window is undecided."""
    out: dict[tuple[str, str], tuple[int, str] | None] = {}
    for key, g in table.groupby(["model", "baseline"], sort=False):
        g = g.sort_values("first")
        last = g["verdict"].iloc[-1]
        other = np.flatnonzero(g["verdict"].to_numpy() != last)  # the windows decided otherwise
        out[key] = None if last == "undecided" else (int(g["first"].iloc[other[-1] + 1 if len(other) else 0]), last)
    return out


def paper_seed_table(summary: pd.DataFrame, paper_last: dict[str, float], paper_model: dict[str, str | None],
                     level: float = 0.95) -> pd.DataFrame:
    """Per variant of `summary` (`training.training_summary`) whose paper model has a curve: the
    prediction interval for one more seed's final reward and where the paper's value lies. `reward`
    says which of our definitions it read: the paper's, estimated, where every seed has it."""
    rows = []
    for variant, g in summary.groupby("model", sort=False):
        model = paper_model.get(str(variant))
        if model is None or model not in paper_last:
            continue
        complete = g.get("reward_complete_last", pd.Series(math.nan, g.index)).to_numpy(float)
        reward = COMPLETE if np.isfinite(complete).all() else CUT
        r = complete if reward == COMPLETE else g["reward_last"].to_numpy(float)
        n, mean, paper = len(r), float(r.mean()), float(paper_last[model])
        if n >= 2:
            half = t_critical(n - 1, level) * float(r.std(ddof=1)) * math.sqrt(1 + 1 / n)
            low, high = mean - half, mean + half
            verdict = "above" if paper > high else "below" if paper < low else "within"
        else:
            low = high = math.nan
            verdict = "one seed"
        rows.append({"variant": str(variant), "paper_model": model, "reward": reward, "seeds": n, "mean": mean,
                     "pi_low": low, "pi_high": high, "paper": paper, "verdict": verdict})
    return pd.DataFrame(rows, columns=PAPER_SEED_COLUMNS)


def _separation_lines(separation: pd.DataFrame, design: Design, window: int) -> list[str]:
    firsts, parts = sorted(separation["first"].unique()), parting(separation)
    records = []
    for (variant, base), g in separation.groupby(["model", "baseline"], sort=False):
        at = parts[(variant, base)]
        cells = {int(r["first"]): _cell(r) for _, r in g.iterrows()}
        records.append({"variant": variant, "baseline": base,
                        "parts": "undecided" if at is None else f"{at[1]} from iteration {at[0]}",
                        **{f"{f}–{f + window - 1}": cells.get(f, "–") for f in firsts}})
    windows = [f"{f}–{f + window - 1}" for f in firsts]
    return [f"Training curves compared: mean episode reward per window of {window} iterations, each variant "
            f"against its baseline ({len(separation)} tests, Holm-corrected; α = {design.alpha:g}):", "",
            *markdown_table(pd.DataFrame(records), {"Variant": "variant", "Baseline": "baseline", "parts at": "parts",
                                                    **{w: w for w in windows}}, "lll" + "r" * len(windows)), "",
            "Each cell: the variant's mean reward minus its baseline's over the window's seeds [the comparison "
            "engine's 95% interval, unadjusted], * where Holm's correction decides it. parts at: the window from "
            "which every later one is decided the same way."]


def _prediction(r: dict) -> str:
    return "–" if math.isnan(r["pi_low"]) else f"[{r['pi_low']:.2f}, {r['pi_high']:.2f}]"


def _paper_seed_lines(paper_seeds: pd.DataFrame) -> list[str]:
    return [f"The paper's one seed against ours: final reward (mean of the last {LAST} iterations), our mean and "
            "the 95% prediction interval for one more seed:", "", *markdown_table(paper_seeds, {
                "Variant": "variant", "paper's model": "paper_model", "our reward": "reward", "seeds": "seeds",
                "our mean": lambda r: f"{r['mean']:.2f}", "one more seed (95%)": _prediction,
                "paper": lambda r: f"{r['paper']:.2f}", "paper's seed": "verdict"}, "lllrrlrl"), "",
            "within: the paper's value could be one of our seeds; above or below: it could not, at 95%. The paper's "
            "reward counts every episode whole (its collector carries episodes across batch ends). our reward: "
            f"{COMPLETE}, the estimate of that definition (`episode_reward_mean_complete`); {CUT}, our logged "
            "`episode_reward_mean` (runs trained before the estimate), which counts the segment a batch's end cuts "
            "as an episode and sits 0.5–0.6 below it on a trained policy (docs/deviations.md)."]


def curve_verdicts_markdown(separation: pd.DataFrame, paper_seeds: pd.DataFrame, design: Design,
                            window: int = WINDOW) -> str:
    parts = ([_separation_lines(separation, design, window)] if len(separation) else []) + \
        ([_paper_seed_lines(paper_seeds)] if len(paper_seeds) else [])
    return "\n\n".join("\n".join(p) for p in parts) + "\n" if parts else ""


def _cell(r: pd.Series) -> str:
    if math.isnan(r["ci_low"]):
        return f"{signed(r['difference'])} (n {r['seeds']})"
    star = "*" if r["verdict"] != "undecided" else ""
    return f"{signed(r['difference'])}{star} [{signed(r['ci_low'])}, {signed(r['ci_high'])}]"
