"""A policy of the paper's own code (SigmaRL's `M<k>_policy.pth`) in our evaluator: the
adaptation to the paper's units against hand-worked numbers and the environment's own speeds,
the action against a plain MLP built from the file, refusals in one line, and a short real
evaluation of the shipped M5 policy."""

from __future__ import annotations

import hashlib
import json
import math

import pandas as pd
import pytest
import torch
from cli_errors import one_line_exit_2

from sigmarl.ablation import MODELS
from sigmarl.cli import main
from sigmarl.compose import compose_config
from sigmarl.env.factory import make_scenario, step_scenario
from sigmarl.evaluation.import_command import policy_file
from sigmarl.evaluation.imported import adapt, imported_policy, load_weights, speed_entries
from sigmarl.maps import scenario_map_config
from sigmarl.rows import check_rows

M5 = policy_file("paper:M5")


def test_the_six_shipped_policies_take_the_sizes_format_md_states():
    sizes = {"M0": 32, "M1": 36, "M2": 26, "M3": 30, "M4": 50, "M5": 31}  # FORMAT.md
    for model in MODELS:
        assert load_weights(policy_file(f"paper:{model}"))[0][0].shape == (256, sizes[model])


def test_adaptation_by_hand():
    """M0 among 4 agents: own speed at 0, the two neighbours' velocities at 18-19 and 29-30."""
    cfg = compose_config(["obs=full"])
    entries = speed_entries(cfg, 4)
    assert (entries.own, entries.others) == ([0], [18, 19, 29, 30])
    obs = torch.zeros(1, 1, 32)
    obs[..., 0], obs[..., 1], obs[..., 18], obs[..., 30] = -0.5, 0.3, 0.25, -1.0
    out = adapt(obs, entries)[0, 0]
    assert out[0].item() == pytest.approx(0.41)  # |-0.5 x 0.8| + 0.01: unsigned, paper's units
    assert out[1].item() == pytest.approx(0.31)  # no speed: only + 0.01
    assert out[18].item() == pytest.approx(0.21)  # 0.25 x 0.8 + 0.01
    assert out[30].item() == pytest.approx(-0.79)  # a neighbour's velocity keeps its sign
    assert out[5].item() == pytest.approx(0.01)


@pytest.mark.parametrize("preset", ["full", "no_ego_view", "no_vertices", "no_distance_to_boundaries"])
def test_speed_entries_are_where_the_environment_writes_speeds(preset):
    """Noise off, our rules: the entries x 0.8 m/s are the vehicles' own speed (or velocity) and
    their two nearest neighbours' velocities, as the environment holds them."""
    cfg = compose_config([f"obs={preset}", "obs.noise=0"])
    sc = make_scenario(cfg, num_envs=2, n_agents=4, mode="test", map_cfg=scenario_map_config("CPM"), seed=3)
    for _ in range(4):
        obs = step_scenario(sc, torch.tensor([0.6, 0.1]).expand(2, 4, 2).contiguous())
    entries = speed_entries(cfg, 4)
    own = obs[..., entries.own] * 0.8
    expected = sc.speed.unsqueeze(-1) if entries.own_is_speed else sc.vel
    assert torch.allclose(own, expected, atol=1e-5)
    others = (obs[..., entries.others] * 0.8).unflatten(-1, (2, 2))  # [E, A, K, 2]
    speeds_of_nearest = sc.vel.norm(dim=-1).gather(1, sc.neighbours.flatten(1)).view(2, 4, 2)
    assert torch.allclose(others.norm(dim=-1), speeds_of_nearest, atol=1e-5)  # a rotation keeps |v|


def _plain_mlp(path) -> torch.nn.Sequential:
    state = torch.load(path, weights_only=True)
    net = torch.nn.Sequential(torch.nn.Linear(31, 256), torch.nn.Tanh(), torch.nn.Linear(256, 256),
                              torch.nn.Tanh(), torch.nn.Linear(256, 4))
    net.load_state_dict({k.removeprefix("module.0.module.0.agent_networks.0."): v for k, v in state.items()})
    return net


@pytest.mark.parametrize("rules, speed", [("paper", 1.0), ("ours", 0.8)])
def test_action_is_the_box_times_tanh_of_loc(rules, speed):
    cfg = compose_config(["obs=no_distance_to_center_line", f"rules={rules}"])
    obs = torch.rand(3, 4, 31, generator=torch.Generator().manual_seed(0)) - 0.5
    action = imported_policy(load_weights(M5), cfg, 4)(obs)
    fed = obs if rules == "paper" else adapt(obs, speed_entries(cfg, 4))
    with torch.no_grad():
        loc = _plain_mlp(M5)(fed)[..., :2]
    box = torch.tensor([speed, math.radians(35)])
    assert torch.allclose(action, box * loc.tanh(), atol=1e-6)


def test_a_file_that_is_no_policy_is_refused_in_one_line(tmp_path, capsys):
    text = tmp_path / "notes.pth"
    text.write_text("not a policy\n")
    line = one_line_exit_2(["evaluate", str(text), "--model", "M5", "--out", str(tmp_path / "o")], capsys)
    assert str(text) in line and "is not a SigmaRL policy file" in line
    other = tmp_path / "other.pth"
    torch.save({"weight": torch.zeros(2, 2)}, other)
    line = one_line_exit_2(["evaluate", str(other), "--model", "M5", "--out", str(tmp_path / "o")], capsys)
    assert "is not a SigmaRL policy file" in line and "weight" in line
    assert not (tmp_path / "o").exists()


def test_a_wrong_model_is_refused_naming_both_sizes(tmp_path, capsys):
    line = one_line_exit_2(["evaluate", str(M5), "--model", "M0", "--out", str(tmp_path / "o"),
                            "--scenario", "CPM"], capsys)
    assert "takes 31 inputs" in line and "model M0's observation (full) has 32" in line
    line = one_line_exit_2(["evaluate", "paper:M5", "--model", "M2", "--out", str(tmp_path / "o")], capsys)
    assert "the paper's M5, not M2" in line


def test_model_and_label_are_refused_for_our_own_checkpoints(tmp_path, capsys):
    line = one_line_exit_2(["evaluate", str(tmp_path / "best.pt"), "--model", "M5"], capsys)
    assert "--model names a SigmaRL policy's model" in line


def test_rows_never_go_into_a_run_folder_nor_without_out(tmp_path, capsys):
    run = tmp_path / "M5" / "seed0"
    run.mkdir(parents=True)
    (run / "config.yaml").write_text("seed: 0\n")
    assert "training run's folder" in one_line_exit_2(["evaluate", "paper:M5", "--out", str(run)], capsys)
    assert "need --out" in one_line_exit_2(["evaluate", "paper:M5"], capsys)
    assert "rules=paper (as it is) or rules=ours" in one_line_exit_2(
        ["evaluate", "paper:M5", "--out", str(tmp_path), "rules=paper_dynamics"], capsys)


def test_a_short_real_evaluation_of_the_shipped_m5_writes_rows_marked_imported(tmp_path, capsys):
    out = tmp_path / "M5-ITSC24" / "paper"
    args = ["evaluate", "paper:M5", "rules=paper", "--out", str(out), "--scenario", "CPM",
            "--scenario", "Roundabout", "eval.n_sims=2", "eval.steps=30"]
    assert main(args) == 0
    rows = pd.read_csv(out / "evaluation_rows.csv")
    check_rows(rows, out / "evaluation_rows.csv", top_speed=1.0)
    sha = hashlib.sha256(M5.read_bytes()).hexdigest()
    assert set(rows["model"]) == {"M5-ITSC24"} and set(rows["source"]) == {"SigmaRL"}
    assert set(rows["policy_sha256"]) == {sha} and set(rows["rules"]) == {"paper"}
    assert set(rows["obs"]) == {"E,V,DA,DB"} and len(rows) == 4
    note = json.loads((out / "evaluation.json").read_text())
    assert (note["policy_sha256"], note["as_model"], note["adaptation"]) == (sha, "M5", "none")
    # the same file, model and protocol again: the saved rows, not a second evaluation
    written = (out / "evaluation_rows.csv").stat().st_mtime_ns
    assert main(args) == 0
    assert (out / "evaluation_rows.csv").stat().st_mtime_ns == written


def test_the_shipped_m5_animates_as_it_drives_in_its_evaluation(tmp_path, capsys):
    """`evaluate paper:M5 --animate`: a GIF of one frame per step, titled with the column and its
    rules, never without its rules being the paper's or ours."""
    import imageio.v3 as iio

    out = tmp_path / "animations"
    assert main(["evaluate", "paper:M5", "--animate", "Roundabout", "--frames", "3", "rules=paper",
                 "--animate-dir", str(out), "eval.n_sims=2"]) == 0
    gif = out / "M5-ITSC24_rules-paper_Roundabout_sim0.gif"
    assert iio.imread(gif, index=None).shape[0] == 3
    assert f"wrote {gif}" in capsys.readouterr().out
    line = one_line_exit_2(["evaluate", "paper:M5", "--animate", "Roundabout", "rules=paper_dynamics"], capsys)
    assert "rules=paper (as it is) or rules=ours" in line


@pytest.mark.slow
def test_an_imported_policys_running_counts_are_its_evaluation_rows(tmp_path):
    """The adapted M5 (our rules) on the Roundabout, simulations 0 and 1 of 2: each film's
    collision counts after 40 steps are its rows' CR_AA and CR_AL times 40."""
    from sigmarl.evaluation.imported import animate_imported, evaluate_imported

    cfg = compose_config([f"obs={MODELS['M5']}", "rules=ours", "eval.n_sims=2", "eval.steps=40"])
    films = animate_imported(M5, cfg, "M5", "M5-ITSC24", "Roundabout", [0, 1], 40, tmp_path, mp4=False)
    rows = evaluate_imported(M5, cfg, "M5", "M5-ITSC24", ["Roundabout"], progress=False).set_index("simulation")
    for k, film in films.items():
        assert (film.agent, film.lane) == (round(rows.loc[k, "CR_AA"] * 40), round(rows.loc[k, "CR_AL"] * 40))
        assert len(film.titles) == 40 and "M5-ITSC24 (rules=ours)" in film.titles[0]
