"""Damaged files found by the third reliability round: every file a user or a crash can damage
is read through one checked reader that answers in one line naming the file and the fix
(exit code 2), and a resume never goes on past a lost iteration."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
import torch
from cli_errors import one_line_exit_2

from sigmarl.errors import SigmarlError
from sigmarl.training import checkpoint as ckpt
from sigmarl.training import metrics_file

PAPER_RUN = Path(__file__).resolve().parents[1] / "results" / "paper-budget" / "M0" / "seed0"




BROKEN_YAML = {
    "study/broken.yaml": "# @package _global_\nstudy:\n  name: broken\n  variants: {M0: [obs=full]\n",
    "study/twice.yaml": "# @package _global_\nstudy:\n  variants:\n    M0: [obs=full]\n    M0: [obs=no_ego_view]\n",
    "scenario/Bad.yaml": "map: cpm\nn_agents: [\n",
    "map/bad_map.yaml": "kind: intersection\nlane_width: [\n",
    "map/binary.yaml": "\x00\xff\xfe",
}


@pytest.mark.parametrize("name", sorted(BROKEN_YAML))
def test_f4_a_broken_yaml_file_in_a_config_folder_is_one_line(name, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("SIGMARL_CONFIG_PATH", raising=False)
    path = tmp_path / "conf" / name
    path.parent.mkdir(parents=True)
    path.write_bytes(BROKEN_YAML[name].encode("latin-1"))
    line = one_line_exit_2(["--config-dir", str(tmp_path / "conf"), "train", "ppo=smoke"], capsys)
    assert str(path) in line and ("line" in line or "UTF-8" in line)
    assert "duplicate key 'M0'" in line if "twice" in name else True


def test_f4_a_broken_scenario_on_the_search_path_is_one_line(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "scenario").mkdir()
    (tmp_path / "scenario" / "Bad.yaml").write_text("map: cpm\nn_agents: [\n")
    monkeypatch.setenv("SIGMARL_CONFIG_PATH", str(tmp_path))  # no --config-dir: read at use
    line = one_line_exit_2(["train", "ppo=smoke", "eval.scenarios=[Bad]"], capsys)
    assert "Bad.yaml, line 3" in line


@pytest.mark.parametrize("content", [
    '["a list"]', "{}", '{"seeds": {"A": [0, 1]}, "previous": {}, "looks": {}, "done": false}',
    '{"seeds": {"A": ["x"]}, "previous": {}, "looks": [], "done": false}', "not json", "\x00\x01"])
def test_f9_a_seeds_auto_record_of_the_wrong_shape_is_one_line(content, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "runs").mkdir()
    record = tmp_path / "runs" / "seeds_auto.json"
    record.write_text(content)
    line = one_line_exit_2(["sweep", "seeds=auto", "models=[M0,M4]", "study.seeds=[0,1]", "tracking.enabled=false",
                            f"runs_root={tmp_path / 'runs'}"], capsys)
    assert str(record) in line and "move it away" in line


@pytest.mark.parametrize("content", [b"\x80\x81binary\xff", b"model: [M0\n", b"- a list\n", b"ppo: {lr: abc}\n"])
def test_f11_a_damaged_config_yaml_in_a_run_folder_is_one_line(content, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    run = tmp_path / "runs" / "M0" / "seed0"
    run.mkdir(parents=True)
    (run / "config.yaml").write_bytes(content)
    line = one_line_exit_2(["sweep", "study=quick", "models=[M0]", "seeds=[0]", "tracking.enabled=false",
                            f"runs_root={tmp_path / 'runs'}"], capsys)
    assert str(run / "config.yaml") in line and "move the run folder away" in line


def _metrics(tmp_path: Path, n: int = 5) -> Path:
    path = tmp_path / "metrics.csv"
    for it in range(1, n + 1):
        metrics_file.append(path, it, {"episode_reward_mean": it / 2, "lr": 1e-4})
    return path


def test_f12_a_resume_keeps_the_rows_up_to_its_checkpoint_and_drops_a_cut_last_line(tmp_path):
    path = _metrics(tmp_path)
    path.write_bytes(path.read_bytes()[:-7])  # a kill while iteration 5 was appended
    assert [it for it, _ in metrics_file.truncate(path, 4)] == [1, 2, 3, 4]
    assert metrics_file.read(path)[-1] == (4, {"episode_reward_mean": 2.0, "lr": 1e-4})


@pytest.mark.parametrize("damage, expected", [
    (lambda b: b[: b.index(b"\n3,")] + b"\n3,1.", "iteration\\(s\\) 3"),  # cut inside a row the checkpoint holds
    (lambda b: b"", "empty"),
    (None, "missing"),
    (lambda b: b + b.splitlines(keepends=True)[2], "twice"),  # a row repeated
    (lambda b: b.replace(b"\n2,", b"\n2,\xff\xfe"), "not text"),
    (lambda b: b.replace(b"\n2,", b"\n2,x"), "line 3"),
    (lambda b: b.replace(b"iteration", b"it"), "header"),
])
def test_f12_a_damaged_metrics_file_is_refused_not_resumed_past(damage, expected, tmp_path):
    path = _metrics(tmp_path)
    if damage is None:
        path.unlink()
    else:
        path.write_bytes(damage(path.read_bytes()))
    before = path.read_bytes() if path.exists() else None
    with pytest.raises(SigmarlError, match=expected) as raised:
        metrics_file.truncate(path, 4)
    assert str(path) in str(raised.value) and "\n" not in str(raised.value)
    assert (path.read_bytes() if path.exists() else None) == before  # left as it was


@pytest.mark.parametrize("slot, value", [("exp_avg", float("nan")), ("exp_avg_sq", float("inf")), ("lr", float("nan"))])
def test_f13_a_resume_point_with_a_nan_optimiser_state_is_refused(slot, value, tmp_path):
    state = torch.load(PAPER_RUN / "checkpoint.pt", weights_only=True)
    if slot == "lr":
        state["optimizer"]["param_groups"][0]["lr"] = value
    else:
        state["optimizer"]["state"][0][slot].view(-1)[3] = value
    path = tmp_path / "checkpoint.pt"
    torch.save(state, path)
    with pytest.raises(SigmarlError, match="optimiser state") as raised:
        ckpt.load(path, resume=True)
    assert str(path) in str(raised.value)
    ckpt.load(path)  # evaluation reads only the policy's weights: still usable
    shutil.copy(PAPER_RUN / "checkpoint.pt", path)
    ckpt.load(path, resume=True)


@pytest.mark.parametrize("content", [
    b"",  # emptied
    b'{"M0/seed0": {"overrides": [], "vari',  # cut
    b"\xff\xfe{}",  # random bytes
    b'["M0/seed0"]',  # valid JSON of the wrong shape
    b'{"M4/seed0": {"overrides": [], "variant": [], "fingerprint": "f"}}',  # another job's plan
    b'{"M0/seed0": {"overrides": "ppo=smoke", "variant": [], "fingerprint": "f"}}',
    b'{"M0/seed0": {"overrides": [1], "variant": [], "fingerprint": "f"}}',
])
def test_a_damaged_sweep_plan_is_one_line_naming_it(content, tmp_path):
    from omegaconf import OmegaConf

    from sigmarl.sweep.job import _job_configs

    plan = tmp_path / "plan.json"
    plan.write_bytes(content)
    with pytest.raises(SigmarlError) as e:
        _job_configs(OmegaConf.create({"study": {"plan": str(plan), "job": "M0/seed0"}}))
    line = str(e.value)
    assert "\n" not in line and str(plan) in line and "run the sweep again" in line


@pytest.mark.parametrize("note", [b"[1, 2]", b'{"eval_key": 3, "dtypes": "x"}', b"\xff", b'"rows"'])
def test_a_damaged_rows_note_means_the_rows_are_measured_again(note, tmp_path):
    from sigmarl.compose import compose_config
    from sigmarl.evaluation.protocol import rows_file_for, saved_rows

    run = tmp_path / "M0" / "seed0"
    run.mkdir(parents=True)
    shutil.copy(PAPER_RUN / "evaluation_rows.csv", run / "evaluation_rows.csv")
    (run / "evaluation.json").write_bytes(note)
    cfg = compose_config(["ppo=smoke"])
    assert rows_file_for(run / "best.pt", cfg).parent == run  # no traceback on a note that is not a record
    assert saved_rows(run / "evaluation_rows.csv", {"eval_key": "k", "checkpoint_sha256": "s"}) is None
