"""findings.md: the study's figures in sentences, from a hand-made summary and verdicts."""

from __future__ import annotations

import pandas as pd

from sigmarl.report.compare.verdicts import findings_markdown


def _summary() -> pd.DataFrame:
    rows = []
    for model, seeds, totals, speeds in [("B", 5, [0.2, 0.9], [0.61, 0.70]), ("V", 3, [3.0, 4.0], [0.5, 0.5])]:
        for scenario, total, speed in zip(["S1", "S2"], totals, speeds, strict=True):
            rows += [{"scenario": scenario, "model": model, "metric": "CR_total", "mean": total, "n_seeds": seeds},
                     {"scenario": scenario, "model": model, "metric": "AS", "mean": speed, "n_seeds": seeds}]
    return pd.DataFrame(rows)


def test_findings_name_the_baselines_worst_scenario_and_each_verdict() -> None:
    verdicts = pd.DataFrame({"scenario": ["S1", "S2"], "metric": "CR_total", "model": "V", "baseline": "B",
                             "seeds": "3/5", "verdict": ["worse", "undecided"]})
    text = findings_markdown(_summary(), verdicts, ["B", "V"], "B", alpha=0.05)
    assert text.startswith("Seeds per model: B 5, V 3. B's total collision rate is at most 0.90 % on each "
                           "of the 2 scenarios (worst: S2, best: S1 at 0.20 %), at an average speed of "
                           "0.61–0.70 m/s.\n")
    assert "Holm-adjusted across all 2 comparisons, α = 0.05" in text
    assert text.endswith("- V against B (CR_total (%), 3 against 5 seeds): worse on S1; undecided on S2.\n")


def test_agreeing_verdicts_say_every_scenario_and_no_baseline_says_no_baseline_sentence() -> None:
    verdicts = pd.DataFrame({"scenario": ["S1", "S2"], "metric": "CR_total", "model": "V", "baseline": "B",
                             "seeds": "3/5", "verdict": "undecided"})
    assert "undecided on every scenario." in findings_markdown(_summary(), verdicts, ["B", "V"], "B")
    assert findings_markdown(_summary(), None, ["B", "V"], None) == "Seeds per model: B 5, V 3.\n"
