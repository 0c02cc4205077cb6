"""The paper's own trained policies (`sigmarl evaluate paper:M<k>`) beside our seeds, per claim of
the replication table: the one policy the paper evaluated per model, measured in our evaluator.

Per (scenario, model), CR_total with the collision rates trimmed as the paper's (each
evaluation's best and worst simulation dropped, as `replication` does):

- the paper's policy under the paper's rules (as it is) and under ours (adapted to our units);
- where it ranks among our seeds of that model: how many of our seed means are lower (under the
  paper's rules, the one that decides);
- its Mk - M0 under either rules, beside Table I's and ours (mean of seed means).

These are descriptions, not tests: the policies are one draw each, never pooled with our seeds,
never in the composite score's normalisers nor in a verdict.

`explanation`, for each claim the replication table does not reproduce (not reproduced, or
reversed), the first of these that a measurement supports:

- **the paper's reward**: the paper-reward study's interaction (Mk - M0 under the paper's reward
  normaliser against ours) is decided in the paper's direction;
- **the paper's own run**: its policy reproduces its difference in our evaluator (its Mk - M0,
  under the paper's rules, lies nearer Table I's than ours) and lies in our seeds' tail (worse, in
  the claim's direction, than `TAIL` of our seeds of that model);
- **seed luck**: the replication table's seed-luck test says the paper's one-seed difference is
  not rare among our seed pairs;
- **unexplained**.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from sigmarl.ablation import flags_of, paper_model
from sigmarl.metrics import CR_TOTAL
from sigmarl.report.cells import trim_collisions
from sigmarl.report.compare.verdicts import seed_values
from sigmarl.report.tables import paper_values, signed

METRIC = CR_TOTAL
TAIL = 0.9  # "in our seeds' tail": worse than at least this share of our seeds of the model
NOT_REPRODUCED = ("not reproduced", "reversed")
RULES = ("paper", "ours")  # the paper's rules (as it is), ours (adapted)
COLUMNS = [
    "claim", "scenario", "metric", "model", "policy", "n_seeds", "table_i", "ours", "policy_paper_rules",
    "policy_our_rules", "seeds_lower", "rank", "seeds_lower_our_rules", "table_i_delta", "ours_delta",
    "policy_delta_paper_rules", "policy_delta_our_rules", "explanation",
]  # fmt: skip


def _policy_values(imported: pd.DataFrame) -> dict[tuple[str, str, str], tuple[str, float]]:
    """(paper model, rules, scenario) -> (label, trimmed mean CR_total) of the imported policies;
    of two labels of one model, the first by name."""
    models = {str(label): paper_model(flags_of(str(obs)))
              for label, obs in zip(imported["model"], imported["obs"], strict=True)}
    # each (label, rules) trimmed as one evaluation of its own
    keyed = imported.assign(model=imported["model"].astype(str) + "\t" + imported["rules"].astype(str), seed=0)
    values: dict[tuple[str, str, str], tuple[str, float]] = {}
    for (key, scenario), [sims] in sorted(seed_values(trim_collisions(keyed), METRIC).items()):
        label, rules = key.split("\t")
        if models[label] is not None and rules in RULES:
            values.setdefault((models[label], rules, scenario), (label, float(sims.mean())))
    return values


def policy_table(rows: pd.DataFrame, imported: pd.DataFrame, models: list[str], baseline: str = "M0") -> pd.DataFrame:
    """One row per (scenario, model) of our `models` (the paper's own, by label) that an imported
    policy of that model was evaluated on under the paper's rules (`COLUMNS`)."""
    policies = _policy_values(imported)
    ours = {k: np.array([g.mean() for g in v]) for k, v in seed_values(trim_collisions(rows), METRIC).items()}
    paper = paper_values()
    records = []
    for scenario in dict.fromkeys(rows["scenario"].astype(str)):
        for model in models:
            seeds, own = ours.get((model, scenario)), policies.get((model, "paper", scenario))
            if seeds is None or own is None:
                continue
            adapted = policies.get((model, "ours", scenario), (None, np.nan))[1]
            record = {"claim": "baseline" if model == baseline else "difference", "scenario": scenario,
                      "metric": METRIC, "model": model, "policy": own[0], "n_seeds": len(seeds),
                      "table_i": _paper(paper, scenario, model), "ours": float(seeds.mean()),
                      "policy_paper_rules": own[1], "policy_our_rules": adapted,
                      "seeds_lower": int((seeds < own[1]).sum()),
                      "rank": f"worse than {int((seeds < own[1]).sum())} of {len(seeds)}",
                      "seeds_lower_our_rules": int((seeds < adapted).sum()) if np.isfinite(adapted) else pd.NA}
            record.update(_deltas(model, baseline, scenario, record, ours, policies, paper))
            records.append(record)
    frame = pd.DataFrame(records, columns=COLUMNS)
    frame["explanation"] = ""  # the claim's explanation (`explain`, with the replication table)
    frame["seeds_lower_our_rules"] = frame["seeds_lower_our_rules"].astype("Int64")
    return frame


def _paper(paper: pd.DataFrame, scenario: str, model: str) -> float:
    key = (scenario, METRIC)
    return float(paper.loc[key, model]) if key in paper.index and model in paper.columns else np.nan


def _deltas(model, baseline, scenario, record, ours, policies, paper) -> dict[str, float]:
    """Mk - M0: Table I's, ours (mean of seed means), the paper's policies' under either rules."""
    if model == baseline or (baseline, scenario) not in ours:
        return {}
    base = {r: policies.get((baseline, r, scenario), (None, np.nan))[1] for r in RULES}
    return {"table_i_delta": record["table_i"] - _paper(paper, scenario, baseline),
            "ours_delta": record["ours"] - float(ours[(baseline, scenario)].mean()),
            "policy_delta_paper_rules": record["policy_paper_rules"] - base["paper"],
            "policy_delta_our_rules": record["policy_our_rules"] - base["ours"]}


def _own_run(r: pd.Series) -> bool:
    """The paper's policy reproduces its difference here and lies in our seeds' tail."""
    claimed, own, ours = r["table_i_delta"], r["policy_delta_paper_rules"], r["ours_delta"]
    if pd.isna(claimed) or pd.isna(own) or pd.isna(ours) or not r["n_seeds"]:
        return False
    worse = r["seeds_lower"] if claimed > 0 else r["n_seeds"] - r["seeds_lower"]
    return abs(own - claimed) < abs(own - ours) and worse >= TAIL * r["n_seeds"]


def explain(table: pd.DataFrame, replication: pd.DataFrame, reward: dict | None = None) -> list[str]:
    """Each row's explanation (see the module's docstring; `–` for a claim that is not
    unreproduced); `reward`: (scenario, model) -> True where the paper-reward interaction is
    decided in the paper's direction (none measured: an empty dict)."""
    reward = reward or {}
    keyed = replication[replication["claim"] == "difference"].set_index(["scenario", "model"])
    out = []
    for _, r in table.iterrows():
        key = (r["scenario"], r["model"])
        if r["claim"] != "difference" or key not in keyed.index or keyed.loc[key, "verdict"] not in NOT_REPRODUCED:
            out.append("–")
        elif reward.get(key):
            out.append("the paper's reward")
        elif _own_run(r):
            out.append("the paper's own run")
        elif keyed.loc[key, "explanation"] == "seed luck":
            out.append("seed luck")
        else:
            out.append("unexplained")
    return out


def _num(x) -> str:
    return "–" if x is None or pd.isna(x) else f"{x:.2f}"


def _delta(x) -> str:
    return "–" if x is None or pd.isna(x) else signed(x, 2)


def policy_markdown(table: pd.DataFrame) -> str:
    """The table as Markdown: per claim, Table I, our seeds and the paper's policy in our evaluator."""
    lines = ["# The paper's own policies in our evaluator", "",
             "CR_total in %, collision rates trimmed as the paper's. policy: the policy the paper evaluated "
             "for Table I (its code's checkpoint), run in our evaluator under the paper's rules (as it is) and "
             "under ours (adapted to our units); rank: among our seeds of that model, under the paper's rules "
             "(how many of our seed means are lower). Δ: minus M0. The policies are never pooled with our "
             "seeds, nor in the composite score or a verdict.", "",
             "| scenario | model | Table I | ours (seeds) | policy, paper's rules | policy, our rules | rank "
             "| Δ Table I | Δ ours | Δ policy, paper's rules | Δ policy, our rules | explanation |",
             "|---|---|---:|---:|---:|---:|---|---:|---:|---:|---:|---|"]
    for _, r in table.iterrows():
        lines.append(f"| {r['scenario']} | {r['model']} ({r['policy']}) | {_num(r['table_i'])} | "
                     f"{_num(r['ours'])} ({r['n_seeds']}) | {_num(r['policy_paper_rules'])} | "
                     f"{_num(r['policy_our_rules'])} | {r['rank']} | {_delta(r['table_i_delta'])} | "
                     f"{_delta(r['ours_delta'])} | {_delta(r['policy_delta_paper_rules'])} | "
                     f"{_delta(r['policy_delta_our_rules'])} | {r['explanation'] or '–'} |")
    return "\n".join(lines) + "\n"
