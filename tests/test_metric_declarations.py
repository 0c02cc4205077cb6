"""A metric is one declaration (`sigmarl.metrics`): the tables, the row checks and the key read
it, and a metric declared after rows were written leaves them valid and their keys as they were."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest

from sigmarl import metrics
from sigmarl.compose import compose_config
from sigmarl.errors import SigmarlError
from sigmarl.eval_key import eval_key
from sigmarl.readers import read_run_config
from sigmarl.rows import check_rows

ROOT = Path(__file__).resolve().parents[1]
FIXTURE = Path(__file__).parent / "data" / "results"


def _study_keys() -> dict[Path, str]:
    """Each study's runs root -> the key of the protocol it evaluates under."""
    keys = {}
    for study in sorted((ROOT / "conf" / "study").glob("*.yaml")):
        cfg = compose_config([f"study={study.stem}"])
        keys[(ROOT / cfg.runs_root).resolve()] = eval_key(cfg.eval)
    return keys


def test_every_committed_evaluation_key_is_unchanged():
    """Each committed row file's note names the key its protocol has today: its study's (by
    the runs root it lies under), else its run's config.yaml's, else the paper's protocol
    (imported policies, no config)."""
    studies = _study_keys()
    files = sorted((ROOT / "results").rglob("evaluation_rows.csv"))
    assert len(files) >= 120
    seen = set()
    for rows in files:
        stored = json.loads((rows.parent / "evaluation.json").read_text())["eval_key"]
        config = rows.parent / "config.yaml"
        now = studies.get(rows.parents[2].resolve()) or (
            eval_key(read_run_config(config).eval) if config.is_file() else eval_key(compose_config([]).eval))
        assert now == stored, rows
        seen.add(stored)
    assert seen == {"e91834283d7e", "33673e29737b"}  # the paper's protocol; the generalisation maps'


def test_a_metric_declared_later_keeps_every_key(monkeypatch):
    cfg = compose_config([]).eval
    before = eval_key(cfg)
    later = metrics.Metric("TTC", "s", 1.0, False, 0, False, required=False, tables=(metrics.BENCHMARK,))
    monkeypatch.setattr(metrics, "METRICS", (*metrics.METRICS, later))
    monkeypatch.setattr(metrics, "MEASURED", [*metrics.MEASURED, "TTC"])
    assert eval_key(cfg) == before


def test_the_tables_read_the_declarations():
    assert metrics.names(metrics.TABLE_I) == ["CR_AA", "CR_AL", "CR_total", "CD", "AS"]
    assert metrics.METRIC_COLUMNS == metrics.names(metrics.TABLE_I)
    assert metrics.names(metrics.PER_SEED) == ["CR_total", "CR_AA", "CR_AL", "CD", "AS"]  # the headline first
    assert metrics.names(metrics.FIGURES) == ["CR_total", "CD", "AS"]
    assert metrics.names(metrics.BENCHMARK) == ["TS", "CAA_100m", "CAL_100m", "LV_100m"]
    assert metrics.REQUIRED == metrics.names(metrics.TABLE_I)  # what every committed row file holds
    assert metrics.BY_NAME["CAA_100m"].heading == "CAA_100m (per 100 m)"
    assert metrics.BY_NAME["TS"].cell(87.5) == "87.50" and metrics.BY_NAME["TS"].cell(float("nan")) == "–"
    assert metrics.BY_NAME["CD"].cell(None) == "–"


def _fixture_rows() -> tuple[pd.DataFrame, Path]:
    path = FIXTURE / "M0" / "seed0" / "evaluation_rows.csv"
    return pd.read_csv(path), path


def test_rows_without_a_later_metric_pass_and_read_not_measured():
    rows, path = _fixture_rows()
    assert not set(metrics.ADDED) & set(rows.columns)
    assert check_rows(rows, path) is rows
    assert metrics.measured(rows) == metrics.REQUIRED


def test_a_later_metric_is_checked_where_it_was_measured():
    rows, path = _fixture_rows()
    rows = rows.assign(TS=0.5, CAA_100m=float("nan"), CAL_100m=1.25, LV_100m=0.0)
    check_rows(rows, path)  # NaN: undefined in that simulation (too little distance)
    with pytest.raises(SigmarlError, match="TS is not a rate in"):
        check_rows(rows.assign(TS=1.5), path)
    with pytest.raises(SigmarlError, match=r"CAL_100m \(per 100 m\) is negative on line 2"):
        check_rows(rows.assign(CAL_100m=-1.0), path)
    with pytest.raises(SigmarlError, match="LV_100m is not a finite number"):
        check_rows(rows.assign(LV_100m=float("inf")), path)
    with pytest.raises(SigmarlError, match="CR_AA is not a finite number"):  # Table I's: never undefined
        check_rows(rows.assign(CR_AA=float("nan")), path)


@pytest.mark.slow
def test_evaluate_adds_the_missing_metrics_only_when_asked(tmp_path, capsys):
    """Rows written before the benchmark's metrics (saved as an older writer did, without their
    columns) are reused as they are; `--add-metrics` evaluates again and adds the columns, every
    saved column's text kept."""
    from sigmarl.cli import main
    from sigmarl.evaluation.protocol import save_rows

    run = tmp_path / "run"
    protocol = ["eval.scenarios=[Intersection]", "eval.n_sims=2", "eval.steps=60", "tracking.enabled=false"]
    assert main(["train", "ppo=smoke", "ppo.iterations=1", f"run_dir={run}", *protocol]) == 0
    assert main(["evaluate", str(run / "final.pt"), *protocol]) == 0
    rows_file, note_file = run / "evaluation_rows.csv", run / "evaluation.json"
    whole = pd.read_csv(rows_file)
    assert metrics.measured(whole) == metrics.MEASURED
    check_rows(whole, rows_file)
    note = json.loads(note_file.read_text())
    identity = {"eval_key": note["eval_key"], "checkpoint_sha256": note["checkpoint_sha256"]}
    older = pd.read_csv(rows_file, dtype=note["dtypes"]).drop(columns=metrics.ADDED)
    save_rows(older, rows_file, identity, compose_config(protocol).eval)
    before = rows_file.read_bytes()

    assert main(["evaluate", str(run / "final.pt"), *protocol]) == 0  # not asked: reused as they are
    assert rows_file.read_bytes() == before

    assert main(["evaluate", str(run / "final.pt"), "--add-metrics", *protocol]) == 0
    text_before = pd.read_csv(pd.io.common.BytesIO(before), dtype=str, keep_default_na=False)
    text_after = pd.read_csv(rows_file, dtype=str, keep_default_na=False)
    assert list(text_after.columns) == [*text_before.columns, *metrics.ADDED]
    pd.testing.assert_frame_equal(text_after[text_before.columns], text_before)  # every saved cell's text
    added = pd.read_csv(rows_file)
    pd.testing.assert_frame_equal(added[metrics.ADDED], whole[metrics.ADDED])  # what one evaluation measures
    check_rows(added, rows_file)
    assert json.loads(note_file.read_text())["added_metrics"] == metrics.ADDED
    assert "TS" in capsys.readouterr().out
