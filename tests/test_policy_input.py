"""The policy's input size from the config alone, against the environment's own observations,
and the refusals built on it: a study that could not be evaluated is refused before it trains."""

from __future__ import annotations

import itertools
import time

import pytest

from sigmarl.ablation import OBS_FLAGS
from sigmarl.cli import main
from sigmarl.compose import compose_config
from sigmarl.env.factory import make_env, make_scenario
from sigmarl.errors import SigmarlError
from sigmarl.policy_input import observation_size

# M0 by hand: own forward speed 1, 3 reference points 6, center-line distance 1, two boundary
# distances 2; per neighbour 4 corners 8, velocity 2, distance 1
M0_OWN, M0_OTHER = 1 + 6 + 1 + 2, 8 + 2 + 1


def test_m0s_size_by_hand() -> None:
    cfg = compose_config(["tracking.enabled=false"])
    assert observation_size(cfg.obs, 4) == M0_OWN + 2 * M0_OTHER == 32
    cfg = compose_config(["tracking.enabled=false", "obs.n_nearest=3"])
    assert observation_size(cfg.obs, 4) == 43 and observation_size(cfg.obs, 3) == 32


def _overrides(flags) -> list[str]:
    return [f"obs.{name}={str(on).lower()}" for name, on in zip(OBS_FLAGS, flags, strict=True)]


ALL = list(itertools.product([True, False], repeat=len(OBS_FLAGS)))
# under the paper's rules, with other reference points and neighbour counts
OTHER = ["rules=paper", "obs.n_ref_points=2", "obs.n_nearest=3"]


def _scenario_size(overrides: list[str], n_agents: int) -> tuple[int, int]:
    cfg = compose_config(["tracking.enabled=false", *overrides])
    obs = make_scenario(cfg, num_envs=1, n_agents=n_agents).current_observation()
    return obs.shape[-1], observation_size(cfg.obs, n_agents)


def test_the_size_is_the_training_environments() -> None:
    """What the policy is built on: the torchrl environment's observation spec in training."""
    cfg = compose_config(["tracking.enabled=false"])
    obs = make_env(cfg, num_envs=1).reset()[("agents", "observation")]
    assert obs.shape[-1] == observation_size(cfg.obs, cfg.env.n_agents) == 32


@pytest.mark.parametrize(("flags", "extra"), [
    (ALL[-1], []),  # every flag off
    ((True, False, True, False, True), OTHER),
    ((False, True, False, True, False), OTHER),
])
def test_the_size_is_a_test_scenarios(flags, extra) -> None:
    """Representative designs in a test scenario of 6 agents (the exhaustive check is slow)."""
    seen, predicted = _scenario_size([*_overrides(flags), *extra], 6)
    assert seen == predicted


@pytest.mark.slow
def test_the_size_is_the_environments_for_every_design() -> None:
    """All 32 observation designs, every other one under the paper's rules and other counts."""
    for i, flags in enumerate(ALL):
        seen, predicted = _scenario_size([*_overrides(flags), *(OTHER if i % 2 else [])], 6)
        assert seen == predicted, flags


def test_more_neighbours_than_training_agents_is_refused_at_composition() -> None:
    with pytest.raises(SigmarlError, match=r"obs.n_nearest=4 needs more than env.n_agents=4"):
        compose_config(["tracking.enabled=false", "obs.n_nearest=4"])
    assert compose_config(["tracking.enabled=false", "obs.n_nearest=4", "env.n_agents=5"]).obs.n_nearest == 4


def test_the_environment_never_caps_the_neighbours() -> None:
    cfg = compose_config(["tracking.enabled=false", "obs.n_nearest=3"])
    with pytest.raises(SigmarlError, match="obs.n_nearest=3 neighbours cannot be observed among 3 agents"):
        make_scenario(cfg, num_envs=1, n_agents=3)


def _own_conf(root, study: str, scenario: str | None = None):
    conf = root / "my_conf"
    (conf / "study").mkdir(parents=True)
    (conf / "study" / "nearest.yaml").write_text(study)
    if scenario:
        (conf / "scenario").mkdir()
        (conf / "scenario" / "Tiny.yaml").write_text(scenario)
    return conf


NEAREST = """\
# @package _global_
study:
  name: nearest
  variants:
    K2: [obs.n_nearest=2]
    {other}
  baseline: K2
  seeds: [0]
  scenarios: {scenarios}
tracking:
  experiment: nearest
"""


def _sweep(conf, root, capsys) -> tuple[int, str, float]:
    import os

    os.environ.pop("SIGMARL_CONFIG_PATH", None)  # an earlier test's --config-dir
    start = time.perf_counter()
    rc = main(["--config-dir", str(conf), "sweep", "study=nearest", "ppo=smoke", "tracking.enabled=false",
               f"runs_root={root}/runs"])
    return rc, capsys.readouterr().err, time.perf_counter() - start


def test_k2_against_k4_with_four_training_agents_is_refused_before_training(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    conf = _own_conf(tmp_path, NEAREST.format(other="K4: [obs.n_nearest=4]", scenarios="[CPM, Intersection]"))
    rc, err, seconds = _sweep(conf, tmp_path, capsys)
    assert rc == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "variant K4" in lines[0] and "obs.n_nearest=4" in lines[0], err
    assert not (tmp_path / "runs").exists() and seconds < 30


def test_a_scenario_with_too_few_agents_is_refused_with_both_sizes(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    conf = _own_conf(tmp_path, NEAREST.format(other="K3: [obs.n_nearest=3]", scenarios="[CPM, Tiny]"),
                     scenario="map: paper_intersection\nn_agents: 3\n")
    rc, err, _ = _sweep(conf, tmp_path, capsys)
    assert rc == 2
    lines = err.strip().splitlines()
    # K3 trains on 4 agents (3 neighbours: 43 inputs); Tiny's 3 agents show 2 (32)
    assert len(lines) == 1 and "variant K3 cannot be evaluated on Tiny" in lines[0], err
    assert "takes 43 inputs" in lines[0] and "have 32 (3 agents, 2 observed neighbours" in lines[0]
    assert not (tmp_path / "runs").exists()
