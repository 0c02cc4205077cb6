"""The report's study page ("study.md") says what it compares: per column its fingerprint and
what it changes against the baseline, the settings all columns share off the defaults, the budget; and a training-reward
comparison across different reward functions is marked not comparable."""

from __future__ import annotations

import pandas as pd
from test_report_tables import hand_rows

from sigmarl.compose import compose_config
from sigmarl.report import BuildOptions, build_report
from sigmarl.report.study import reward_differs, shared_settings, study_markdown


def _rows(models: dict[str, list[int]], sims: int = 2) -> pd.DataFrame:
    return pd.DataFrame([{"model": m, "seed": s, "scenario": sc, "simulation": k}
                         for m, seeds in models.items() for s in seeds for sc in ("CPM", "Roundabout")
                         for k in range(sims)])


def test_columns_say_their_fingerprint_their_change_and_the_shared_command_line():
    line = ["env.n_agents=5", "ppo=smoke"]  # what a sweep's command line gave every column
    configs = {"M0": compose_config([*line, "obs=full"]), "M4": compose_config([*line, "obs=no_distance_to_boundaries"])}
    text = study_markdown(configs, _rows({"M0": [0, 1], "M4": [0, 1, 2]}), ["M0", "M4"], "M0",
                          compose_config([]), "abc123")
    assert f"| M0 | `{configs['M0'].fingerprint}` | 2 (0, 1) | (baseline) |" in text
    assert f"| M4 | `{configs['M4'].fingerprint}` | 3 (0, 1, 2) | `obs.distance_to_boundaries=false` |" in text
    assert "- `env.n_agents=5` (default 4)" in text  # shared and off the default: shown once, not per column
    smoke = configs["M0"].ppo
    assert f"- training: {smoke.iterations:,} iterations, {smoke.iterations * smoke.frames_per_iteration:,} frames" in text
    assert "- seeds: 2–3 a column" in text
    assert "2 scenarios (CPM, Roundabout) × 2 simulations" in text and "commit abc123" in text
    assert "not comparable" not in text


def test_defaults_only_say_none_and_a_missing_config_is_named():
    configs = {"M0": compose_config([])}
    text = study_markdown(configs, _rows({"M0": [0], "M1": [0]}), ["M0", "M1"], "M0", compose_config([]), None)
    assert "- none: every shared setting is the default" in text
    assert "No training config on this machine for M1" in text and "not a git checkout" in text


def test_different_rewards_are_marked_not_comparable():
    a, b = compose_config([]), compose_config(["env.reward.progress=20"])
    assert reward_differs([a, b]) == ["env.reward.progress"] and reward_differs([a, a]) == []
    assert shared_settings([a, b], a) == []  # a setting they do not share is no shared setting
    text = study_markdown({"R0": a, "R1": b}, _rows({"R0": [0], "R1": [0]}), ["R0", "R1"], "R0", a, "c")
    assert "train on different rewards (env.reward.progress)" in text
    assert "| R1 | " in text and "`env.reward.progress=20" in text


def test_table_md_opens_with_the_header_and_the_latex_caption_says_each_columns_change(tmp_path):
    line = ["env.n_agents=5"]
    configs = {"M0": compose_config([*line, "obs=full"]), "M4": compose_config([*line, "obs=no_distance_to_boundaries"])}
    report = build_report(hand_rows(["M0", "M4"]), BuildOptions(
        out_dir=tmp_path, models=["M0", "M4"], baseline="M0", latex=True, figures=False, configs=configs,
        defaults=compose_config([]), commit="abc123"))
    table = (tmp_path / "table.md").read_text(encoding="utf-8")
    head, rest = table.split("\n## Table\n", 1)
    assert head.startswith("# What this table compares")
    assert f"| M4 | `{configs['M4'].fingerprint}` | 1 (0) | `obs.distance_to_boundaries=false` |" in head
    assert "- `env.n_agents=5` (default 4)" in head and "4 scenarios (CPM, Intersection, On-Ramp, Roundabout) × 3 simulations" in head
    assert "| Scenario | Metric | M0 | M4 |" in rest and report.markdown == table
    assert "abc123" not in table  # the commit is the study page's: the same rows give the same table at any commit
    tex = (tmp_path / "table.tex").read_text(encoding="utf-8")
    cap = next(ln for ln in tex.splitlines() if ln.startswith("\\caption{"))
    assert r"Columns: M0: baseline; M4: obs.distance\_to\_boundaries=false." in cap
    assert r"All: env.n\_agents=5 (default 4)." in cap and "seeds: 1 a column" in cap
