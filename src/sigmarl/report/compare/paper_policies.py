"""The paper's own trained policies (`sigmarl evaluate paper:M<k>`; docs/concepts.md) beside our
seeds, per claim of the replication table, CR_total trimmed as the paper's: each policy in our
evaluator under the paper's rules and under ours (adapted), how many of our seed means of its
model lie below it, and its Mk - M0 beside Table I's and ours (`deltas`). Descriptions, not tests:
the policies are one draw each, never pooled with our seeds, in the composite or in a verdict.

`explanation`, for each claim the replication table does not reproduce (not reproduced, or
reversed), the first a measurement supports: **the paper's reward** (the paper-reward study's
interaction on the claim is decided in the paper's direction); **the paper's own run** (the
policy's Mk - M0 under the paper's rules lies nearer Table I's than ours, and the policy lies in
our seeds' tail, worse in the claim's direction than `TAIL` of them); **seed luck** (the
replication table's seed-luck test); else **unexplained**.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from sigmarl.ablation import flags_of, paper_model
from sigmarl.metrics import CR_TOTAL
from sigmarl.report.cells import trim_collisions
from sigmarl.report.compare.verdicts import seed_means
from sigmarl.report.tables import markdown_table, paper_values, signed

METRIC = CR_TOTAL
TAIL = 0.9  # "in our seeds' tail": worse than at least this share of our seeds of the model
NOT_REPRODUCED = ("not reproduced", "reversed")
RULES = ("paper", "ours")  # the paper's rules (as it is), ours (adapted)
# every value CR_total in %; each Mk - M0 is its row's minus M0's row's (`deltas`)
COLUMNS = ["scenario", "model", "policy", "n_seeds", "table_i", "ours", "policy_paper_rules", "policy_our_rules",
           "seeds_lower", "seeds_lower_our_rules", "explanation"]
DELTAS = ["table_i", "ours", "policy_paper_rules", "policy_our_rules"]


def _policy_values(imported: pd.DataFrame) -> dict[tuple[str, str, str], tuple[str, float]]:
    """(paper model, rules, scenario) -> (label, trimmed mean CR_total) of the imported policies;
    of two labels of one model, the first by name."""
    models = {str(label): paper_model(flags_of(str(obs)))
              for label, obs in zip(imported["model"], imported["obs"], strict=True)}
    # each (label, rules) trimmed as one evaluation of its own
    keyed = imported.assign(model=imported["model"].astype(str) + "\t" + imported["rules"].astype(str), seed=0)
    values: dict[tuple[str, str, str], tuple[str, float]] = {}
    for (key, scenario), [mean] in sorted(seed_means(trim_collisions(keyed), METRIC).items()):
        label, rules = key.split("\t")
        if models[label] is not None and rules in RULES:
            values.setdefault((models[label], rules, scenario), (label, float(mean)))
    return values


def policy_table(rows: pd.DataFrame, imported: pd.DataFrame, models: list[str]) -> pd.DataFrame:
    """One row per (scenario, model) of our `models` (the paper's own, by label) that an imported
    policy of that model was evaluated on under the paper's rules (`COLUMNS`)."""
    policies = _policy_values(imported)
    ours = seed_means(trim_collisions(rows), METRIC)
    paper = paper_values()
    records = []
    for scenario in dict.fromkeys(rows["scenario"].astype(str)):
        for model in models:
            seeds, own = ours.get((model, scenario)), policies.get((model, "paper", scenario))
            if seeds is None or own is None:
                continue
            adapted = policies.get((model, "ours", scenario), (None, np.nan))[1]
            key = (scenario, METRIC)
            records.append({
                "scenario": scenario, "model": model, "policy": own[0], "n_seeds": len(seeds),
                "table_i": float(paper.loc[key, model]) if key in paper.index and model in paper.columns else np.nan,
                "ours": float(seeds.mean()), "policy_paper_rules": own[1], "policy_our_rules": adapted,
                "seeds_lower": int((seeds < own[1]).sum()),
                "seeds_lower_our_rules": int((seeds < adapted).sum()) if np.isfinite(adapted) else pd.NA})
    frame = pd.DataFrame(records, columns=COLUMNS)
    frame["explanation"] = ""  # the claim's explanation (`explain`, with the replication table)
    frame["seeds_lower_our_rules"] = frame["seeds_lower_our_rules"].astype("Int64")
    return frame


def deltas(table: pd.DataFrame, baseline: str = "M0") -> pd.DataFrame:
    """Mk - M0 of each of `DELTAS`: the row's minus the baseline's row of its scenario (NaN on the
    baseline's own rows, or where its scenario has none)."""
    base = table[table["model"] == baseline].set_index("scenario")[DELTAS].reindex(table["scenario"])
    return (table[DELTAS] - base.to_numpy()).where(table["model"] != baseline)


def _own_run(r: pd.Series, d: pd.Series) -> bool:
    """The paper's policy reproduces its difference here (its Mk - M0 `d` under the paper's rules
    nearer Table I's than ours) and lies in our seeds' tail."""
    claimed, own, ours = d["table_i"], d["policy_paper_rules"], d["ours"]
    if pd.isna(claimed) or pd.isna(own) or pd.isna(ours) or not r["n_seeds"]:
        return False
    worse = r["seeds_lower"] if claimed > 0 else r["n_seeds"] - r["seeds_lower"]
    return abs(own - claimed) < abs(own - ours) and worse >= TAIL * r["n_seeds"]


def explain(table: pd.DataFrame, replication: pd.DataFrame, reward: dict | None = None,
            baseline: str = "M0") -> list[str]:
    """Each row's explanation (see the module's docstring; `–` for a claim that is not
    unreproduced); `reward`: (scenario, model) -> True where the paper-reward interaction is
    decided in the paper's direction (none measured: an empty dict)."""
    reward = reward or {}
    keyed = replication.set_index(["scenario", "model"])
    out = []
    for (_, r), (_, d) in zip(table.iterrows(), deltas(table, baseline).iterrows(), strict=True):
        key = (r["scenario"], r["model"])
        if r["model"] == baseline or key not in keyed.index or keyed.loc[key, "verdict"] not in NOT_REPRODUCED:
            out.append("–")
        elif reward.get(key):
            out.append("the paper's reward")
        elif _own_run(r, d):
            out.append("the paper's own run")
        elif keyed.loc[key, "explanation"] == "seed luck":
            out.append("seed luck")
        else:
            out.append("unexplained")
    return out


def _num(x) -> str:
    return "–" if x is None or pd.isna(x) else f"{x:.2f}"


def policy_markdown(table: pd.DataFrame, baseline: str = "M0") -> str:
    """The table as Markdown: per claim, Table I, our seeds and the paper's policy in our evaluator."""
    shown = pd.concat([table, deltas(table, baseline).add_prefix("d_")], axis=1)
    delta = {f"Δ {name}": lambda r, k="d_" + c: signed(r[k], 2) for name, c in (
        ("Table I", "table_i"), ("ours", "ours"), ("policy, paper's rules", "policy_paper_rules"),
        ("policy, our rules", "policy_our_rules"))}
    lines = ["# The paper's own policies in our evaluator", "",
             "CR_total in %, collision rates trimmed as the paper's. policy: the policy the paper evaluated "
             "for Table I (its code's checkpoint), run in our evaluator under the paper's rules (as it is) and "
             "under ours (adapted to our units); rank: among our seeds of that model, under the paper's rules "
             "(how many of our seed means are lower). Δ: minus M0. The policies are never pooled with our "
             "seeds, nor in the composite score or a verdict.", "", *markdown_table(shown, {
                 "scenario": "scenario", "model": lambda r: f"{r['model']} ({r['policy']})",
                 "Table I": lambda r: _num(r["table_i"]), "ours (seeds)": lambda r: f"{_num(r['ours'])} ({r['n_seeds']})",
                 "policy, paper's rules": lambda r: _num(r["policy_paper_rules"]),
                 "policy, our rules": lambda r: _num(r["policy_our_rules"]),
                 "rank": lambda r: f"worse than {r['seeds_lower']} of {r['n_seeds']}", **delta,
                 "explanation": lambda r: r["explanation"] or "–"}, "llrrrrlrrrrl")]
    return "\n".join(lines) + "\n"
