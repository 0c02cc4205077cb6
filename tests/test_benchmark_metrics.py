"""The CPM Lab benchmark's metrics (`sigmarl.evaluation.benchmark`) against hand-worked
scripted trajectories: known contacts, speeds, respawns and goals."""

from __future__ import annotations

import math

import pandas as pd
import torch

from sigmarl.evaluation.benchmark import BenchmarkSums, Hysteresis
from sigmarl.metrics import CAA_100M, CAL_100M, LV_100M, TS


def _events(sequence: str, contact_steps: int, clear_steps: int) -> list[int]:
    """The steps at which events start, for one agent's contacts written as 0/1 characters."""
    h = Hysteresis((1,), contact_steps=contact_steps, clear_steps=clear_steps)
    return [t for t, c in enumerate(sequence) if bool(h.step(torch.tensor([c == "1"]))[0])]


def test_one_long_contact_is_one_event():
    # 3 steps in contact start it (step 2); 2 clear steps do not end it, so the contact at 6-8 is
    # the same event; 5 clear steps (9-13) end it; the contact at 14-16 is a new one (step 16)
    assert _events("11110011100000111", 3, 5) == [2, 16]
    # our counting: the first contact step starts an event; clear at 3..7 ends the one from 0
    assert _events("101000001", 1, 5) == [0, 8]
    assert _events("1111111111", 1, 5) == [0]
    assert _events("1000001000001", 1, 5) == [0, 6, 12]


def test_the_hysteresis_is_batched_per_agent():
    h = Hysteresis((2, 2), contact_steps=1, clear_steps=2)
    script = [[[1, 0], [0, 1]], [[1, 0], [0, 0]], [[0, 1], [0, 0]], [[0, 1], [0, 1]]]
    counts = sum(h.step(torch.tensor(s, dtype=torch.bool)).long() for s in script)
    assert counts.tolist() == [[1, 1], [0, 2]]


def _drive(sums: BenchmarkSums, steps: int, speeds, contacts: dict, goals) -> None:
    """One simulation of two agents: `contacts` maps a step (1-based) to
    (agent-agent flags, agent-lane flags, respawned flags), each a pair."""
    for k in range(1, steps + 1):
        aa, al, respawned = contacts.get(k, ((0, 0), (0, 0), (0, 0)))
        t = lambda flags: torch.tensor([flags], dtype=torch.bool)  # noqa: E731
        sums.add(t(aa), t(al), torch.tensor([speeds]), t(respawned), torch.tensor([goals]))


def test_a_scripted_trajectory_gives_the_hand_worked_metrics():
    # agent 0 laps a 2.49 m loop at 1 m/s (0.05 m a step): laps end at steps 50, 100, 150, 200
    # (carries 0.01, 0.02, ...): 4 successes. Agent 1 drives a route with an exit at 0.5 m/s: a
    # lane contact at step 20 (respawn: failure), an agent contact at 60 (failure) and again at
    # 63, three steps later (failure, but the same event: not 5 steps clear), the exit at 150.
    sums = BenchmarkSums(1, 2, "cpu")
    inf = math.inf
    contacts = {20: ((0, 0), (0, 1), (0, 1)), 60: ((0, 1), (0, 0), (0, 1)), 63: ((0, 1), (0, 0), (0, 1)),
                150: ((0, 0), (0, 0), (0, 1))}
    _drive(sums, 200, (1.0, 0.5), contacts, (2.49, inf))
    got = {k: float(v[0]) for k, v in sums.columns().items()}
    distance = 200 * 0.05 + 200 * 0.025  # 15 m
    assert math.isclose(got[TS], 5 / 8)  # 4 laps + 1 exit; 3 collisions
    # float32 sums, as every tensor of a rollout (a device may lack float64): 1e-5 relative
    assert math.isclose(got[CAA_100M], 1 * 100 / distance, rel_tol=1e-5)
    assert math.isclose(got[CAL_100M], 1 * 100 / distance, rel_tol=1e-5)
    assert math.isclose(got[LV_100M], 0.025 * 100 / distance, rel_tol=1e-5)  # one step's distance in a lane contact


def test_a_policy_that_barely_moves_has_no_per_100m_values():
    sums = BenchmarkSums(1, 2, "cpu")
    _drive(sums, 100, (0.01, 0.0), {30: ((1, 1), (0, 0), (1, 1))}, (9.0, 9.0))  # 0.05 m in all
    got = {k: float(v[0]) for k, v in sums.columns().items()}
    assert all(math.isnan(got[k]) for k in (CAA_100M, CAL_100M, LV_100M))
    assert got[TS] == 0.0  # two tries ended, both in a collision
    still = BenchmarkSums(1, 2, "cpu")
    _drive(still, 10, (0.0, 0.0), {}, (9.0, 9.0))
    assert math.isnan(float(still.columns()[TS][0]))  # no try ended: undefined


def _rows(with_benchmark: dict[tuple[str, int], list[float]]) -> pd.DataFrame:
    """Two simulations of M0 seeds 0 and 1 and M1 seed 0 on Intersection; (model, seed) in
    `with_benchmark` measured TS for its two simulations, the others did not."""
    records = []
    for model, seed in (("M0", 0), ("M0", 1), ("M1", 0)):
        for sim in range(2):
            r = {"model": model, "seed": seed, "scenario": "Intersection", "simulation": sim,
                 "CR_AA": 0.0, "CR_AL": 0.0, "CR_total": 0.0, "CD": 1.0, "AS": 0.5}
            if (model, seed) in with_benchmark:
                r.update(TS=with_benchmark[model, seed][sim], CAA_100m=2.0, CAL_100m=float("nan"), LV_100m=0.0)
            records.append(r)
    return pd.DataFrame(records)


def test_the_benchmark_table_weighs_seeds_equally_and_shows_not_measured(tmp_path):
    from sigmarl.report.tables import benchmark_estimates, benchmark_markdown

    # M0: seed 0 TS 0.5 and 1.0 (mean 0.75), seed 1 TS NaN and 0.25 (mean 0.25): (0.75 + 0.25) / 2
    rows = _rows({("M0", 0): [0.5, 1.0], ("M0", 1): [float("nan"), 0.25]})
    est = benchmark_estimates(rows, ["M0", "M1"]).set_index("model")
    assert math.isclose(est.loc["M0", TS], 50.0)  # in percent
    assert math.isclose(est.loc["M0", CAA_100M], 2.0) and math.isnan(est.loc["M0", CAL_100M])
    assert est.loc["M1"].drop("scenario").isna().all()  # not measured in M1's rows
    text = benchmark_markdown(est.reset_index())
    assert "| Intersection | M0 | 50.00 | 2.00 | – | 0.00 |" in text
    assert "| Intersection | M1 | – | – | – | – |" in text
    assert "not measured in these rows" in text


def test_a_report_of_rows_from_before_the_benchmark_writes_no_benchmark_table(tmp_path):
    from sigmarl.report.build import build_report
    from sigmarl.report.draft import BuildOptions
    from sigmarl.report.sections import BENCHMARK_TABLE, TABLE

    build_report(_rows({}), BuildOptions(out_dir=tmp_path / "old", figures=False), sections=[TABLE, BENCHMARK_TABLE])
    assert not (tmp_path / "old" / "benchmark.md").exists()
    build_report(_rows({("M1", 0): [0.0, 1.0]}), BuildOptions(out_dir=tmp_path / "new", figures=False),
                 sections=[TABLE, BENCHMARK_TABLE])
    assert "| Intersection | M1 | 50.00 |" in (tmp_path / "new" / "benchmark.md").read_text()
    assert (tmp_path / "old" / "table.md").read_bytes() == (tmp_path / "new" / "table.md").read_bytes()
