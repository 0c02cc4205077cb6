"""The report's study page ("study.md") says what it compares: per column its fingerprint and
what it changes against the baseline, the settings all columns share off the defaults, the budget; and a training-reward
comparison across different reward functions is marked not comparable."""

from __future__ import annotations

import pandas as pd

from sigmarl.compose import compose_config
from sigmarl.report.study_header import reward_differs, shared_settings, study_markdown


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
