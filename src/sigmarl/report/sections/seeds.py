"""The seeds' sections of the report: the training curves' summary, each model-seed's figures
and where a next seed will land."""

from __future__ import annotations

from sigmarl.report.draft import Draft, Section
from sigmarl.report.seeds.next_seed import next_seed_markdown, prediction_table, slow_seed_table
from sigmarl.report.seeds.per_seed import seed_table, seeds_markdown
from sigmarl.report.table.aggregate import scenario_order
from sigmarl.report.table.header import reward_differs
from sigmarl.report.table.paper import paper_curves
from sigmarl.report.table.training import paper_last_rewards, training_markdown, training_summary


def training_section(d: Draft) -> None:
    """The training curves' summary."""
    if d.curves is None:
        return
    d.training = training_summary(d.curves, d.models)
    last = paper_last_rewards(paper_curves()) if d.options.compare_paper else None
    d.write("training", "training.csv", d.training)
    text = training_markdown(d.training, last)
    configs = [d.options.configs[m] for m in d.models if m in (d.options.configs or {})]
    if differ := reward_differs(configs):  # sums of different reward functions
        text = (f"Not comparable across columns: they train on different rewards ({', '.join(differ)}); "
                "each column's rewards compare only with its own seeds.\n\n") + text
    d.write("training_md", "training.md", text)


TRAINING = Section("training", {
    "training.csv": "per seed: iterations, compute time, last and best reward",
    "training.md": "the same per model (the paper's Fig. 5 beside it with `--compare-paper`); where the columns "
                   "train on different rewards it opens by saying their rewards are not comparable"},
    training_section, when="when training curves (`metrics.csv`) are read")


def seeds_section(d: Draft) -> None:
    """Each model-seed's rates, deviation, speed and rewards, and where a next seed will land."""
    seeds = seed_table(d.rows, d.curves, d.models)
    scenarios = scenario_order(d.rows)
    prediction = prediction_table(seeds, scenarios)
    design = d.design
    slow = slow_seed_table(seeds, {v: design.baseline_of(v) for v in design.compared}, design.slow_seed)
    d.write("seeds", "seeds.csv", seeds)
    d.write("seed_prediction", "seed_prediction.csv", prediction)
    d.write("slow_seeds", "slow_seeds.csv", slow)
    spread = next_seed_markdown(prediction, slow, scenarios)
    d.write("seeds_md", "seeds.md", seeds_markdown(seeds, scenarios) + ("\n" + spread if spread else ""))


SEEDS = Section("seeds", {
    "seeds.csv": "each evaluated model-seed's collision rates per scenario, its worst one, center-line "
                 "deviation, speed range and reward over three windows of training",
    "seeds.md": "the same as Markdown; per model with 5 seeds or more, Spearman's correlation of a seed's "
                "reward with its collisions, and where a next seed will land",
    "seed_prediction.csv": "per model and scenario: the next seed's 95% prediction interval of CR_total and "
                           "the seeds' range",
    "slow_seeds.csv": "with `study.slow_seed`: each variant's slow seeds against its baseline's, Fisher's "
                      "exact p"}, seeds_section)
