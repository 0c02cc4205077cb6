"""What a new user meets first: answers without seconds of imports, Hydra's conventions
(`--cfg`, `--info`, `--version`, completion, "did you mean"), `threads` in every command, and
a smoke budget kept out of the paper study's folders."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from importlib import metadata
from pathlib import Path

import pytest
import yaml

from sigmarl.cli import build_parser, main
from sigmarl.cli.completion import bash_script
from sigmarl.compose import compose_config
from sigmarl.errors import SigmarlError

HEAVY = ("torch", "torchrl", "vmas", "mlflow", "pandas", "matplotlib")


def _cli_in_fresh_process(args: list[str], cwd: Path) -> tuple[int, list[str], str]:
    """Run the CLI in a new interpreter; its exit code, the heavy modules it imported, stderr."""
    code = (f"import sys, json\nfrom sigmarl.cli import main\nrc = main({args!r})\n"
            f"print(json.dumps([rc, [m for m in {HEAVY!r} if m in sys.modules]]))")
    proc = subprocess.run([sys.executable, "-c", code], cwd=cwd, capture_output=True, text=True,
                          env=dict(os.environ), timeout=300)
    rc, heavy = json.loads(proc.stdout.strip().splitlines()[-1])
    return rc, heavy, proc.stderr


@pytest.mark.parametrize("args, message", [
    (["train", "ppo.epoch=3"], "did you mean ppo.epochs?"),
    (["evaluate", "nonexistent.pt"], "checkpoint not found: nonexistent.pt"),
    (["report"], "nothing to report: no MLflow store"),
    (["evaluate", "abc123"], "'abc123' is no checkpoint file or run folder, and there is no MLflow store"),
])
def test_answers_that_need_no_torch_import_none_and_create_no_store(tmp_path, args, message):
    rc, heavy, err = _cli_in_fresh_process(args, tmp_path)
    assert rc == 2 and message in err and len(err.strip().splitlines()) == 1, err
    assert heavy == []
    assert list(tmp_path.iterdir()) == []  # no mlflow.db, no run folder


@pytest.mark.parametrize("override, hint", [
    ("ppo.epoch=3", "did you mean ppo.epochs?"),
    ("+ppo.epoch=3", "did you mean ppo.epochs?"),
    ("obs.ego_veiw=false", "did you mean obs.ego_view?"),
    ("obs=ful", "did you mean obs=full?"),
    ("ppo=smok", "did you mean ppo=smoke?"),
    ("hydra/launcher=jobli", "did you mean hydra/launcher=joblib?"),
])
def test_a_typo_gets_a_suggestion_on_one_line(capsys, override, hint):
    assert main(["train", override]) == 2
    err = capsys.readouterr().err
    assert hint in err and len(err.strip().splitlines()) == 1, err


def test_group_choices_leave_out_the_schema_entries(capsys):
    assert main(["train", "obs=foo"]) == 2
    err = capsys.readouterr().err
    assert "base_obs" not in err
    assert "options: full, no_distance_to_agents" in err


def test_cfg_job_prints_the_composed_config(capsys):
    assert main(["train", "--cfg", "job", "ppo.epochs=7", "obs=no_vertices"]) == 0
    cfg = yaml.safe_load(capsys.readouterr().out)
    assert cfg["ppo"]["epochs"] == 7 and cfg["model"] == "M2"
    assert cfg["run_dir"] == "runs/sigmarl-ablation/M2/seed0"


def test_cfg_job_of_a_sweep_prints_each_job(capsys):
    assert main(["sweep", "--cfg", "job", "models=[M0,M4]", "seeds=[0,1]"]) == 0
    out = capsys.readouterr().out
    docs = [yaml.safe_load(part.split("\n", 1)[1]) for part in out.split("# job: ")[1:]]
    assert sorted((d["model"], d["seed"]) for d in docs) == [("M0", 0), ("M0", 1), ("M4", 0), ("M4", 1)]


def test_cfg_hydra_shows_the_sweeps_launcher(capsys):
    assert main(["sweep", "--cfg", "hydra", "models=[M0]", "hydra.launcher.n_jobs=1"]) == 0
    hydra = yaml.safe_load(capsys.readouterr().out)["hydra"]
    assert hydra["launcher"]["n_jobs"] == 1 and "JoblibLauncher" in hydra["launcher"]["_target_"]


def test_version_and_info(capsys):
    with pytest.raises(SystemExit) as done:
        main(["--version"])
    assert done.value.code == 0
    assert capsys.readouterr().out.strip() == f"sigmarl {metadata.version('sigmarl')}"
    with pytest.raises(SystemExit):
        main(["--info"])
    out = capsys.readouterr().out
    assert "ppo             paper, smoke" in out and "base_" not in out


def test_info_lists_the_users_config_folders_beside_the_package(tmp_path, monkeypatch, capsys):
    """`--config-dir` (before --info) and $SIGMARL_CONFIG_PATH: each folder numbered, its study,
    map and scenario listed on their group's line after the package's, a shadowing name starred."""
    monkeypatch.delenv("SIGMARL_CONFIG_PATH", raising=False)
    mine, theirs = tmp_path / "my_conf", tmp_path / "lab_conf"
    for folder, files in ((mine, {"study/narrow.yaml": "# @package _global_\nstudy:\n  name: narrow\n",
                                  "map/my_map.yaml": "defaults:\n  - base_map\n\nname: my_map\nkind: roundabout\n",
                                  "scenario/My-Map.yaml": "map: my_map\nn_agents: 4\n"}),
                          (theirs, {"study/quick.yaml": "# @package _global_\nstudy:\n  name: quick\n"})):
        for name, text in files.items():
            (folder / name).parent.mkdir(parents=True, exist_ok=True)
            (folder / name).write_text(text)
    monkeypatch.setenv("SIGMARL_CONFIG_PATH", str(theirs))
    with pytest.raises(SystemExit) as done:
        main(["--config-dir", str(mine), "--info"])
    assert done.value.code == 0
    lines = capsys.readouterr().out.splitlines()
    assert f"your config folder [1]: {theirs} (searched first; a name it shares shadows sigmarl's, marked *)" in lines
    assert any(line.startswith(f"your config folder [2]: {mine} ") for line in lines)
    study = next(line for line in lines if line.startswith("  study "))
    assert study.endswith("widths; [1] quick*; [2] narrow") and ", quick," in study
    assert next(line for line in lines if line.startswith("  map ")).endswith("roundabout_2; [2] my_map")
    assert next(line for line in lines if line.startswith("scenarios")).endswith("roundabout_2; [2] My-Map")
    monkeypatch.delenv("SIGMARL_CONFIG_PATH")
    with pytest.raises(SystemExit):
        main(["--info"])
    out = capsys.readouterr().out
    assert "your config folder" not in out and "[1]" not in out and "My-Map" not in out
    with pytest.raises(SystemExit) as done:
        main(["--config-dir", str(tmp_path / "nowhere"), "--info"])
    assert done.value.code == 2 and "no such folder" in capsys.readouterr().err


def _complete(line: str) -> list[str]:
    """What bash completes at the end of `line` with the script `--completion bash` prints."""
    script = bash_script(build_parser())
    words = line.split(" ")
    driver = (f"{script}\nCOMP_LINE={line!r}; COMP_POINT={len(line)}; COMP_WORDS=({' '.join(map(repr, words))}); "
              f"COMP_CWORD={len(words) - 1}; _sigmarl; printf '%s\\n' \"${{COMPREPLY[@]}}\"")
    out = subprocess.run(["bash", "-c", driver], capture_output=True, text=True, check=True).stdout
    return out.split()


def test_bash_completes_commands_groups_and_keys():
    assert _complete("sigmarl sw") == ["sweep"]
    # bash splits `obs=no_e` at `=`: the reply completes the part after it
    assert _complete("sigmarl train obs=no_e") == ["no_ego_view"]
    assert _complete("sigmarl train ppo.epo") == ["ppo.epochs="]
    assert _complete("sigmarl sweep see") == ["seed=", "seeds="]
    assert "base_obs" not in _complete("sigmarl train obs=")


def test_smoke_budget_has_its_own_experiment_and_folders():
    cfg = compose_config(["ppo=smoke"])
    assert cfg.tracking.experiment == "sigmarl-smoke" and cfg.run_dir == "runs/sigmarl-smoke/M0/seed0"
    assert cfg.ppo.iterations == 3 and cfg.ppo.lr == compose_config([]).ppo.lr  # the rest stays the paper's
    assert compose_config(["ppo=smoke", "tracking.experiment=mine"]).run_dir == "runs/mine/M0/seed0"
    assert compose_config(["study=quick"]).tracking.experiment == "sigmarl-quick"
    assert compose_config([]).tracking.experiment == "sigmarl-ablation"


@pytest.fixture
def torch_threads():
    import torch

    before = torch.get_num_threads()
    yield torch
    torch.set_num_threads(before)


@pytest.mark.slow
def test_evaluate_runs_on_the_threads_it_is_given(tmp_path, monkeypatch, torch_threads):
    from sigmarl.evaluation import protocol

    run = tmp_path / "run"
    assert main(["train", "ppo=smoke", "ppo.iterations=1", "tracking.enabled=false", "threads=2",
                 f"run_dir={run}"]) == 0
    assert torch_threads.get_num_threads() == 2
    seen = []
    evaluate_policy = protocol.evaluate_policy

    def watched(*args, **kwargs):  # the real evaluation, noting the threads it ran on
        seen.append(torch_threads.get_num_threads())
        return evaluate_policy(*args, **kwargs)

    monkeypatch.setattr(protocol, "evaluate_policy", watched)
    assert main(["evaluate", str(run / "final.pt"), "--scenario", "Intersection", "eval.n_sims=1",
                 "eval.steps=3", "tracking.enabled=false", "threads=1"]) == 0
    assert seen == [1]


@pytest.mark.slow
def test_a_finished_sweep_is_answered_from_its_run_folders(tmp_path, monkeypatch):
    from sigmarl.sweep import finished, plan_sweep

    def all_finished(user):
        return all(finished(job) for job in plan_sweep(user).jobs)

    monkeypatch.chdir(tmp_path)
    tiny = ["models=[M0]", "ppo=smoke", "ppo.iterations=1", "eval.n_sims=1", "eval.steps=5",
            "eval.scenarios=[Intersection]", "hydra/launcher=basic"]
    assert main(["sweep", *tiny]) == 0
    # the job's own log holds its progress, named, in plain lines
    log = (tmp_path / "multirun" / "sigmarl-smoke" / "M0" / "seed0" / "sweep.log").read_text()
    assert "M0 seed 0: train 1/1 (100%) reward" in log
    assert "M0 seed 0: evaluate Intersection 5/5 (100%)" in log
    store = (tmp_path / "mlflow.db").stat().st_mtime_ns
    rc, heavy, err = _cli_in_fresh_process(["sweep", *tiny], tmp_path)
    assert rc == 0, err
    assert heavy == []  # neither the launcher's jobs nor MLflow were started
    assert (tmp_path / "mlflow.db").stat().st_mtime_ns == store
    # another evaluation protocol, or another training setting, is work to do
    assert not all_finished([*tiny, "eval.steps=6"])
    assert all_finished([*tiny, "threads=2"])  # threads change no result
    with pytest.raises(SigmarlError, match="holds a run of another training config"):
        all_finished([*tiny, "ppo.iterations=2"])  # another training setting: refused, never reused


RESULTS = Path(__file__).parent / "data" / "results"


def test_evaluation_runs_nest_under_their_training_run_in_the_tables_units(tmp_path):
    import pandas as pd
    from mlflow import MlflowClient

    from sigmarl.tracking import connect, experiment_id, records

    uri = f"sqlite:///{tmp_path}/mlflow.db"
    client = connect(compose_config([f"tracking.tracking_uri={uri}"]))
    exp = experiment_id(client, "nest", create=True)
    training = client.create_run(exp, run_name="M0-seed0", tags={"kind": "training"}).info.run_id
    rows = pd.read_csv(RESULTS / "M0" / "seed0" / "evaluation_rows.csv")
    rid = records.log_evaluation(client, exp, rows, {"model": "M0", "seed": "0", "train_run_id": training,
                                                     "eval_key": "k"}, {})
    run = MlflowClient(tracking_uri=uri).get_run(rid)
    assert run.data.tags["mlflow.parentRunId"] == training
    cpm = rows[rows["scenario"] == "CPM"]
    # at the table's precision (2 decimals), never a float32 mean's tail
    assert run.data.metrics["CPM/CR_total_pct"] == round(100 * cpm["CR_total"].mean(), 2)
    assert run.data.metrics["CPM/CD_cm"] == round(cpm["CD"].mean(), 2)
    assert run.data.metrics["CPM/AS_mps"] == round(cpm["AS"].mean(), 2)
    # the report reads the rows back in their own units, as from runs logged before
    back = records.load_evaluation_rows(client, "nest")
    assert back["CR_total"].tolist() == pytest.approx(rows["CR_total"].tolist())


def test_report_runs_are_named_after_what_they_report(tmp_path, monkeypatch):
    from mlflow import MlflowClient

    monkeypatch.chdir(tmp_path)
    uri = f"sqlite:///{tmp_path}/mlflow.db"
    assert main(["report", "--from", str(RESULTS), "--no-figures", f"tracking.tracking_uri={uri}",
                 "tracking.experiment=named"]) == 0
    client = MlflowClient(tracking_uri=uri)
    (run,) = client.search_runs([client.get_experiment_by_name("named").experiment_id])
    assert run.info.run_name.startswith(f"report {RESULTS}: M0 vs M4 on ")
    assert run.data.params["baseline"] == "M0" and run.data.params["models"] == "M0,M4"


def test_progress_outside_a_terminal_is_plain_lines_with_an_eta(monkeypatch, capsys):
    from sigmarl import progress

    clock = iter(range(0, 1000, 10))  # each reading of the clock is 10 s after the last
    monkeypatch.setattr(progress.time, "monotonic", lambda: next(clock))
    monkeypatch.delenv("SIGMARL_SWEEP_DIR", raising=False)
    bar = progress.Progress(4, "M3 seed 2", "train", min_interval=0)  # clock 0
    for k in range(4):
        bar.update(1, reward=f"{k / 10:.3f}")  # clock 10, 20, 30, 40 at the k-th line
    bar.close()
    lines = capsys.readouterr().err.strip().splitlines()
    # after 1 of 4 in 10 s: 3 more take 30 s; after 3 of 4 in 30 s: 10 s more
    assert lines == ["M3 seed 2: train 1/4 (25%) reward 0.000 | 10s, ETA 30s",
                     "M3 seed 2: train 2/4 (50%) reward 0.100 | 20s, ETA 20s",
                     "M3 seed 2: train 3/4 (75%) reward 0.200 | 30s, ETA 10s",
                     "M3 seed 2: train 4/4 (100%) reward 0.300 | 40s"]


def test_progress_lines_are_spaced_by_the_interval(monkeypatch, capsys):
    from sigmarl import progress

    clock = iter(range(0, 1000, 4))
    monkeypatch.setattr(progress.time, "monotonic", lambda: next(clock))
    monkeypatch.delenv("SIGMARL_SWEEP_DIR", raising=False)
    bar = progress.Progress(10, "M0 seed 0", "evaluate CPM", min_interval=10)
    for _ in range(10):
        bar.update(1)
    shown = [line.split()[5] for line in capsys.readouterr().err.strip().splitlines()]
    # the first, then one at least 10 s after the last shown (every third step at 4 s each), the last
    assert shown == ["1/10", "4/10", "7/10", "10/10"]
