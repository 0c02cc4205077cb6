"""One validation pass at composition: a bad value ends in one line naming its key, exit code
2, before any run folder, MLflow store or environment exists; and the device a command runs
on is the command's, not the one a checkpoint was trained on."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch
from cli_errors import one_line_exit_2 as _one_line_exit_2

from sigmarl.compose import compose_config
from sigmarl.errors import SigmarlError

PAPER_BEST = Path(__file__).resolve().parents[1] / "results" / "paper-budget" / "M0" / "seed0" / "best.pt"




@pytest.mark.parametrize("override, key", [
    ("obs.ref_point_stride=3", "obs.ref_point_stride"),  # 3 points x 3 = 9 > the 6 ahead
    ("obs.ref_point_stride=0", "obs.ref_point_stride"),
    ("seed=-1", "seed"),
    ("seed=4294967296", "seed"),  # 2**32: beyond numpy's seeds
    ("map.kind=motorway", "map.kind"),
    ("map.route_set=everything", "map.route_set"),
    ("network.activation=gelu", "network.activation"),
    ("ppo.loss=fast", "ppo.loss"),
    ("ppo.precision=fp16", "ppo.precision"),
    ("device=tpu", "device"),
    ("eval.checkpoint=last", "eval.checkpoint"),
    ("tracking.experiment=" + "x" * 10_000, "tracking.experiment"),
    ("env.n_agents=0", "env.n_agents"),
    ("ppo.checkpoint_every=0", "ppo.checkpoint_every"),
])
def test_train_refuses_a_bad_value_in_one_line_before_creating_anything(override, key, tmp_path, capsys,
                                                                        monkeypatch):
    monkeypatch.chdir(tmp_path)
    line = _one_line_exit_2(["train", override, f"runs_root={tmp_path / 'runs'}", "ppo=smoke"], capsys)
    assert key in line
    assert list(tmp_path.iterdir()) == []  # no run folder, no mlflow.db


def test_a_seed_of_ten_thousand_digits_is_one_line(tmp_path, capsys, monkeypatch):
    # Python refuses to parse an int of over 4300 digits: a ValueError inside Hydra's parser
    monkeypatch.chdir(tmp_path)
    for command in ("train", "sweep"):
        line = _one_line_exit_2([command, "seed=" + "7" * 10_000], capsys)
        assert "4300 digits" in line
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("override", ["seed=-1", "tracking.experiment=" + "y" * 10_000])
def test_a_sweep_refuses_a_bad_value_before_any_mlflow_run(override, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    _one_line_exit_2(["sweep", "study=quick", "models=[M0]", override], capsys)
    assert list(tmp_path.iterdir()) == []  # no mlflow.db (so no FAILED run), no runs/, no multirun/


def test_torchrl_loss_is_refused_at_composition_with_any_precision():
    # training has one loss (torchrl's ClipPPOLoss is its oracle in tests/test_ppo_loss.py)
    for precision in ("bf16", "auto", "fp32"):
        with pytest.raises(SigmarlError, match="ppo.loss='torchrl' is not one of lean"):
            compose_config(["ppo.loss=torchrl", f"ppo.precision={precision}"])
    compose_config(["ppo.loss=lean", "ppo.precision=bf16"])


def test_the_paper_defaults_and_every_preset_pass():
    compose_config([])
    for study in ("paper", "quick", "extended"):
        compose_config([f"study={study}"])
    for name in ("cpm", "intersection", "on_ramp", "roundabout", "paper_intersection", "osm"):
        overrides = [f"map={name}"] + (["map.path=x.osm"] if name == "osm" else [])
        compose_config(overrides)


def test_animation_runs_on_the_commands_device_not_the_checkpoints(tmp_path):
    """A checkpoint trained on a GPU (its saved config says device=cuda) animates on this CPU
    machine, as `sigmarl evaluate` evaluates it."""
    from sigmarl.evaluation.animation import animate_checkpoint

    if torch.cuda.is_available():
        pytest.skip("the point is a machine without CUDA")
    state = torch.load(PAPER_BEST, weights_only=True)
    state["config"]["device"] = "cuda"
    gpu_trained = tmp_path / "best.pt"
    torch.save(state, gpu_trained)
    out = animate_checkpoint(gpu_trained, ["On-Ramp"], steps=3, seed=1, out_dir=tmp_path / "report",
                             device="cpu")
    assert out["animation_On-Ramp"].is_file()


def test_the_activation_choices_are_the_networks():
    from dataclasses import fields

    from sigmarl.config import NetworkConfig
    from sigmarl.config.ranges import range_of
    from sigmarl.training.networks import ACTIVATIONS

    (activation,) = [f for f in fields(NetworkConfig) if f.name == "activation"]
    assert set(range_of(activation).choices) == set(ACTIVATIONS)


def test_more_agents_than_the_map_can_hold_are_refused_before_the_env_is_built():
    from conftest import straight_road_map

    from sigmarl.env.factory import make_env

    # one straight 4 m route; spacing 1.2 x the 0.16 x 0.08 m box's diagonal = 0.2147 m:
    # at most floor(4 / 0.2147) + 1 = 19 vehicles
    with pytest.raises(SigmarlError, match="could not place 20 agents on map straight: its routes hold at most 19 vehicles"):
        make_env(compose_config([]), num_envs=2, n_agents=20, road_map=straight_road_map())
