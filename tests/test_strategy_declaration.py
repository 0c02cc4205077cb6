"""An observation strategy is one declaration (`sigmarl.ablation.STRATEGIES`). A toy sixth one,
the agent's own heading, is declared in one place, before anything reads the table (in a
fresh interpreter: ObsConfig's flags are made from it at import). Then the config key, the
vector, its size, the label and the fingerprint follow it, while every committed run keeps
reading as the model it was (M0..M5) and keeps its fingerprint."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
ROWS = sorted(ROOT.glob("results/*/*/seed*/evaluation_rows.csv"))
# and the paper's own policies evaluated (`M<k>-ITSC24/<rules>/`): no run config of ours
# (the rule-based driver's rows aside: it observes nothing, so its obs flags name no paper model)
LABELLED = [*(p for p in ROWS if p.parts[-4] != "rule-based"),
            *sorted(ROOT.glob("results/paper-policies/*/*/evaluation_rows.csv"))]
TOY = "own_heading"


def declare_toy() -> None:
    """The whole of the toy strategy: one entry in the table."""
    from sigmarl import ablation as a

    a.STRATEGIES.append(a.Strategy(TOY, "H", "observe the own heading", a.Block(
        a.OWN, lambda o: int(o.own_heading),
        a.when_on(TOY, lambda v: [(v.x.heading / (2 * math.pi)).unsqueeze(-1)]))))


def _inputs():
    import torch

    from sigmarl.env.observation import ObsInputs

    g = torch.Generator().manual_seed(3)
    n_env, n, k = 2, 4, 2
    r = lambda *s: torch.randn(*s, generator=g)  # noqa: E731
    nb = torch.stack([torch.randperm(n, generator=g)[:k] for _ in range(n_env * n)]).view(n_env, n, k)
    return ObsInputs(pos=r(n_env, n, 2), heading=r(n_env, n), speed=r(n_env, n), vel=r(n_env, n, 2),
                     ref_points=r(n_env, n, 3, 2), d_center=r(n_env, n), d_left=r(n_env, n), d_right=r(n_env, n),
                     left_points=r(n_env, n, 5, 2), right_points=r(n_env, n, 5, 2), corners=r(n_env, n, 4, 2),
                     neighbours=nb, distances=r(n_env, n, n).abs())


def check_with_toy() -> None:
    import torch

    from sigmarl.ablation import MODELS, flags_of, model_label, obs_strategies, paper_model
    from sigmarl.compose import compose_config
    from sigmarl.env.factory import make_scenario
    from sigmarl.env.observation import build_observation
    from sigmarl.identity import fingerprint
    from sigmarl.policy_input import observation_size
    from sigmarl.readers import read_run_config

    off, on = compose_config(["tracking.enabled=false"]), compose_config(["tracking.enabled=false", f"obs.{TOY}=true"])
    # the key exists, is off by default, and M0 stays the paper's five
    assert getattr(off.obs, TOY) is False and off.model == "M0" and list(MODELS) == [f"M{k}" for k in range(6)]
    assert obs_strategies(on.obs) == "E,V,DA,DB,DC,H" and on.model == model_label(on.obs) != "M0"
    assert on.model.startswith("custom-") and paper_model(on.obs) is None
    assert fingerprint(on) != fingerprint(off)
    # the vector: M0's with the heading / 2 pi after the own blocks (1 + 6 + 1 + 2 entries)
    x = _inputs()
    a, b = build_observation(x, off.obs), build_observation(x, on.obs)
    assert torch.equal(b[..., :10], a[..., :10]) and torch.equal(b[..., 11:], a[..., 10:])
    assert torch.equal(b[..., 10], x.heading / (2 * math.pi))
    assert b.shape[-1] == observation_size(on.obs, 4) == observation_size(off.obs, 4) + 1 == 33
    seen = make_scenario(on, num_envs=1, n_agents=4).current_observation().shape[-1]
    assert seen == 33, seen
    # every committed run: its config reads the toy as off, its fingerprint is the one its rows
    # recorded; and every committed row file reads as the paper model its label names
    for path in ROWS:
        cfg = read_run_config(path.parent / "config.yaml")
        rows = pd.read_csv(path, dtype={"obs": str, "fingerprint": str}, keep_default_na=False)
        assert getattr(cfg.obs, TOY) is False, path
        if "fingerprint" in rows.columns:
            assert set(rows["fingerprint"]) == {fingerprint(cfg)}, path
    for path in LABELLED:
        rows = pd.read_csv(path, usecols=["model", "obs"], dtype=str, keep_default_na=False)
        for model, obs in set(zip(rows["model"], rows["obs"], strict=True)):
            assert paper_model(flags_of(obs)) == model.split("-")[0], (path, model, obs)
    print("toy strategy followed", len(ROWS))


def test_a_declared_strategy_is_followed_everywhere_and_changes_no_committed_run() -> None:
    assert ROWS, "no committed evaluation rows"
    done = subprocess.run([sys.executable, __file__], capture_output=True, text=True, cwd=ROOT, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    assert f"toy strategy followed {len(ROWS)}" in done.stdout


def test_committed_rows_read_as_their_paper_models_as_declared_now() -> None:
    from sigmarl.ablation import flags_of, paper_model

    models = {}
    for path in LABELLED:
        rows = pd.read_csv(path, usecols=["model", "obs"], dtype=str, keep_default_na=False)
        models.update({m: paper_model(flags_of(o)) for m, o in zip(rows["model"], rows["obs"], strict=True)})
    assert models == {m: m.split("-")[0] for m in models}
    assert set(models.values()) == {f"M{k}" for k in range(6)}


if __name__ == "__main__":
    declare_toy()
    check_with_toy()
