"""The paper's own policies beside our seeds (`compare.paper_policies`): with `--compare-paper`
and imported rows (`BuildOptions.imported`), per claim of the replication table."""

from __future__ import annotations

import pandas as pd

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
        # the paper-reward study's interactions are not read yet (0 of its seeds finished)
        table["explanation"] = explain(table, pd.read_csv(d.paths["replication"]))
    d.write("paper_policies", "paper_policies.csv", table)
    d.write("paper_policies_md", "paper_policies.md", policy_markdown(table) if len(table) else None)


PAPER_POLICIES = Section("paper_policies", {
    "paper_policies.csv": "per claim of `replication.csv` (and M0): the paper's own policy's CR_total in our "
                          "evaluator under the paper's rules and under ours (adapted), its rank among our seeds "
                          "of that model, its Mk - M0 beside Table I's and ours; `explanation`: each unreproduced claim's "
                          "(the paper's reward, the paper's own run, seed luck or unexplained)",
    "paper_policies.md": "the same as Markdown"},
    paper_policies_section,
    when="with `--compare-paper` and the paper's policies' rows (results/paper-policies/ beside the --from folder)")
