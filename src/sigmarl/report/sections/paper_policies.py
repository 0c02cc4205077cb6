"""The paper's own policies beside our seeds (`compare.paper_policies`): with `--compare-paper`
and imported rows (`BuildOptions.imported`), per claim of the replication table."""

from __future__ import annotations

from dataclasses import asdict

import pandas as pd

from sigmarl.report.compare.interactions import PAPERS_WAY
from sigmarl.report.compare.paper_policies import explain, policy_markdown, policy_table
from sigmarl.report.draft import Draft, Section


def paper_policies_section(d: Draft) -> None:
    """The paper's policy per model: its CR_total in our evaluator under either rules, its rank
    among our seeds, its Mk - M0 beside Table I's; over the columns that are the paper's models."""
    imported = d.options.imported
    if not d.options.compare_paper or imported is None or not len(imported):
        return
    paper = d.paper_models
    own = [m for m in d.models if paper[m] == m]
    table = policy_table(d.rows[d.rows["model"].isin(own)], imported, own, "M0")
    if "replication" in d.paths and len(table):  # each unreproduced claim's explanation
        replication = pd.read_csv(d.paths["replication"])
        table["explanation"] = explain(table, replication, reward_explains(replication, d.options.configs or {}))
    d.write("paper_policies", "paper_policies.csv", table)
    d.write("paper_policies_md", "paper_policies.md", policy_markdown(table) if len(table) else None)


def reward_explains(replication: pd.DataFrame, configs: dict) -> dict[tuple[str, str], bool]:
    """(scenario, model) -> True where the claim's interaction is decided in the paper's direction
    and its condition is the paper's reward: the interaction's column was trained with
    `rules.reward_normaliser_one` on, the claim's model with it off, every other rule alike."""
    if "interaction_verdict" not in replication:
        return {}
    out = {}
    for _, r in replication[replication["interaction_verdict"] == PAPERS_WAY].iterrows():
        x, y = configs.get(str(r["interaction"])), configs.get(str(r["model"]))
        if x is not None and y is not None:
            a, b = asdict(x.rules), asdict(y.rules)
            if {k for k in a if a[k] != b[k]} == {"reward_normaliser_one"} and a["reward_normaliser_one"]:
                out[(str(r["scenario"]), str(r["model"]))] = True
    return out


PAPER_POLICIES = Section("paper_policies", {
    "paper_policies.csv": "per claim of `replication.csv` (and M0): the paper's own policy's CR_total in our "
                          "evaluator under the paper's rules and under ours (adapted), its rank among our seeds "
                          "of that model, its Mk - M0 beside Table I's and ours; `explanation`: each unreproduced claim's "
                          "(the paper's reward, where `replication.csv`'s interaction under the paper's reward is "
                          "decided in the paper's direction; the paper's own run, seed luck or unexplained)",
    "paper_policies.md": "the same as Markdown"},
    paper_policies_section,
    when="with `--compare-paper` and the paper's policies' rows (results/paper-policies/ beside the --from folder)")
