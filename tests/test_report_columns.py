"""A column is a config (`sigmarl.results.columns`): a run under a study variant's label whose
training config is another (a quick-budget M0 evaluated into the paper study's experiment) is
refused in one line naming both fingerprints and what differs, or left out with --partial and
said so in the report; a newer evaluation of another config does not hide the declared one's."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
from cli_errors import one_line_exit_2
from mlflow import MlflowClient

from sigmarl.cli import main
from sigmarl.compose import compose_config
from sigmarl.tracking.records import log_evaluation

FIXTURE = Path(__file__).parent / "data" / "results"


def _store(tmp_path: Path, m0_fingerprints: list[str], m4: bool = True) -> tuple[str, Path]:
    """A store whose experiment holds M4 seed 0 as the paper study composes it, and M0 seed 0
    evaluated once per fingerprint given (in that order); M0 seed 0's config folder is the quick
    budget's (what the refusal reads for what differs)."""
    uri = f"sqlite:///{tmp_path / 'mlflow.db'}"
    client = MlflowClient(uri)
    exp = client.create_experiment("ablation")
    m4 = m4 and compose_config(["study=paper", "obs=no_distance_to_boundaries", "model=M4"]).fingerprint
    quick = tmp_path / "runs" / "M0" / "seed0"
    quick.mkdir(parents=True)
    compose_config(["ppo=smoke", "model=M0"])  # composes, so its config can be written as a run's
    for model, fps in ((("M4", [m4]),) if m4 else ()) + (("M0", m0_fingerprints),):
        rows = pd.read_csv(FIXTURE / model / "seed0" / "evaluation_rows.csv")
        for fp in fps:
            log_evaluation(client, exp, rows, {"model": model, "seed": "0", "fingerprint": fp,
                                               "checkpoint": str(quick / "final.pt")}, {})
    return uri, quick


def _args(uri: str, tmp_path: Path, *more: str) -> list[str]:
    return ["report", "study=paper", "--models", "M0,M4", f"tracking.tracking_uri={uri}",
            "tracking.experiment=ablation", f"runs_root={tmp_path / 'runs'}", "--no-figures",
            "--out", str(tmp_path / "out"), *more]


def test_a_quick_m0_in_the_paper_experiment_is_refused_naming_both_fingerprints(tmp_path, capsys):
    paper = compose_config(["study=paper", "obs=full", "model=M0"])
    quick = compose_config(["ppo=smoke", "obs=full", "model=M0"])
    assert paper.fingerprint != quick.fingerprint
    uri, folder = _store(tmp_path, [quick.fingerprint])
    # the run's own config, for what differs
    from omegaconf import OmegaConf

    from sigmarl.config import as_dict

    (folder / "config.yaml").write_text(OmegaConf.to_yaml(as_dict(quick)))
    capsys.readouterr()
    line = one_line_exit_2(_args(uri, tmp_path), capsys)
    assert f"M0 seed 0 was trained with fingerprint {quick.fingerprint}, not the variant's {paper.fingerprint}" in line
    assert "ppo.iterations: 3 -> 250" in line  # the smoke budget against the paper's
    assert "--partial" in line


def test_a_quick_m0_alone_in_the_paper_experiment_is_refused_too(tmp_path, capsys):
    """The sequence a new user typed: the only column is the quick M0, so nothing shows that its
    budget is the study's command line (found by scripts/probe.py: reported as the paper's M0)."""
    paper = compose_config(["study=paper", "obs=full", "model=M0"])
    quick = compose_config(["ppo=smoke", "obs=full", "model=M0"])
    uri, _ = _store(tmp_path, [quick.fingerprint], m4=False)
    args = [a for a in _args(uri, tmp_path) if a not in ("--models", "M0,M4")]
    line = one_line_exit_2(args, capsys)
    assert f"fingerprint {quick.fingerprint}, not the variant's {paper.fingerprint}" in line
    assert not (tmp_path / "out").exists()


def test_partial_does_not_count_it_as_the_variant(tmp_path, capsys):
    quick = compose_config(["ppo=smoke", "obs=full", "model=M0"]).fingerprint
    uri, _ = _store(tmp_path, [quick])
    capsys.readouterr()
    line = one_line_exit_2(_args(uri, tmp_path, "--partial"), capsys)
    assert "no evaluation rows for model(s) M0" in line  # left out, so the baseline has none


def test_a_newer_evaluation_of_another_config_does_not_hide_the_declared_one(tmp_path, capsys):
    paper = compose_config(["study=paper", "obs=full", "model=M0"]).fingerprint
    quick = compose_config(["ppo=smoke", "obs=full", "model=M0"]).fingerprint
    uri, _ = _store(tmp_path, [paper, quick])  # the quick one evaluated last
    capsys.readouterr()
    assert main(_args(uri, tmp_path, "--partial")) == 0
    table = (tmp_path / "out" / "table.md").read_text(encoding="utf-8")
    assert "Left out: M0 seed 0" in table
    rows = pd.read_csv(tmp_path / "out" / "table.csv")
    assert "M0" in set(rows.columns) | set(rows.iloc[:, 0].astype(str))  # the paper's M0 is reported
