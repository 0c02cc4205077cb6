"""`sigmarl report --from <folder>` on tests/data/results (a real smoke study: M0 and M4,
seeds 0 and 1, trained at ppo=smoke, evaluated 3 simulations x 40 steps per scenario;
regenerate with tests/data/make_results_fixture.py)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pandas as pd
import pytest
from mlflow import MlflowClient

from sigmarl.cli import main
from sigmarl.eval_key import RULES_REVISION
from sigmarl.metrics import METRIC_COLUMNS
from sigmarl.results.folders import read_results
from sigmarl.scenarios import PAPER_SCENARIOS

FIXTURE = Path(__file__).parent / "data" / "results"
TABLE_FILES = ["table.md", "table.csv", "table.tex", "summary.csv", "composite_scores.csv",
               "improvement.csv", "aggregate_scores.csv", "statistics.md"]


def report(tmp_path: Path, out: str, *args: str, source: Path = FIXTURE) -> int:
    return main(["report", "--from", str(source), "--out", str(tmp_path / out), *args,
                 "tracking.enabled=false"])


def test_rebuild_is_byte_identical(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # tracking off: nothing may appear in the working folder
    assert report(tmp_path, "a", "--latex", "--compare-paper", "--ci", "--no-figures") == 0
    assert report(tmp_path, "b", "--latex", "--compare-paper", "--ci", "--no-figures") == 0
    for name in TABLE_FILES:
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes(), name
    assert not (tmp_path / "mlflow.db").exists() and not (tmp_path / "mlruns").exists()


def test_table_holds_seed_level_means_of_the_folder(tmp_path):
    assert report(tmp_path, "out", "--no-figures") == 0
    table = pd.read_csv(tmp_path / "out" / "table.csv")
    ours = table[table["source"] == "ours"].set_index(["scenario", "metric"])
    assert list(ours.columns[-2:]) == ["M0", "M4"]
    # independently: read every evaluation_rows.csv, mean per seed, then over the seeds
    rows = pd.concat([pd.read_csv(p) for p in FIXTURE.glob("*/seed*/evaluation_rows.csv")])
    assert sorted(rows["seed"].unique()) == [0, 1] and len(rows) == 2 * 2 * 4 * 3
    per_seed = rows.groupby(["scenario", "model", "seed"])[METRIC_COLUMNS].mean()
    means = per_seed.groupby(["scenario", "model"]).mean()
    for (scenario, model), m in means.iterrows():
        for metric in METRIC_COLUMNS:
            scale = 100 if metric.startswith("CR") else 1
            assert ours.loc[(scenario, metric), model] == pytest.approx(scale * m[metric], abs=1e-8)
    assert set(ours.index.get_level_values("scenario")) == set(PAPER_SCENARIOS)
    markdown = (tmp_path / "out" / "table.md").read_text()
    assert "Mean over 2 seeds of each seed's mean" in markdown
    stats = (tmp_path / "out" / "statistics.md").read_text()
    assert "| Scenario | M0 vs M4 |" in stats and "| M4 |" in stats


def test_one_seed_a_model_decides_nothing_and_shows_no_interval(tmp_path):
    """The quick study's shape (one seed a model): every comparison and every claim of the paper
    undecided, and no interval where one seed leaves nothing to resample."""
    source = tmp_path / "results"
    shutil.copytree(FIXTURE, source)
    for seed in source.glob("*/seed1"):
        shutil.rmtree(seed)
    assert report(tmp_path, "out", "--no-figures", "--compare-paper", source=source) == 0
    out = tmp_path / "out"
    stats = (out / "statistics.md").read_text()
    assert "[–]" in stats and "[1.00, 1.00]" not in stats
    assert set(pd.read_csv(out / "verdicts.csv")["verdict"]) == {"undecided"}
    assert pd.read_csv(out / "verdicts.csv")["ci_low"].isna().all()
    claims = pd.read_csv(out / "replication.csv")
    assert len(claims) and set(claims["verdict"]) <= {"undecided", "struck out by the paper"}
    assert (claims["verdict"] == "undecided").any()


@pytest.mark.slow
def test_figures_with_and_without_training_metrics(tmp_path):
    source = tmp_path / "results"
    shutil.copytree(FIXTURE, source)
    (source / "M4" / "seed1" / "metrics.csv").unlink()  # one run without training metrics
    results = read_results(source)
    assert sorted(set(zip(results.curves["model"], results.curves["seed"], strict=True))) == [("M0", 0), ("M0", 1), ("M4", 0)]
    assert results.curves["iteration"].tolist()[:3] == [1, 2, 3]
    assert report(tmp_path, "out", source=source) == 0
    for name in ("training_curves.png", "distributions.png", "scenario_maps.png"):
        assert (tmp_path / "out" / name).stat().st_size > 1000
    for path in source.glob("*/seed*/metrics.csv"):
        path.unlink()
    assert report(tmp_path, "bare", source=source) == 0
    assert not (tmp_path / "bare" / "training_curves.png").exists()
    assert (tmp_path / "bare" / "table.md").exists()


def test_unevaluated_runs_are_named_and_left_out(tmp_path, capsys):
    source = tmp_path / "results"
    shutil.copytree(FIXTURE, source)
    (source / "M4" / "seed1" / "evaluation_rows.csv").unlink()
    assert report(tmp_path, "out", "--no-figures", source=source) == 0
    out = capsys.readouterr().out
    assert "M4/seed1: not evaluated yet, training unfinished (no final.pt): left out" in out
    summary = pd.read_csv(tmp_path / "out" / "summary.csv")
    assert set(summary.loc[summary["model"] == "M4", "n_seeds"]) == {1}


def test_rows_measured_under_older_rules_are_left_out(tmp_path, capsys):
    # evaluation.json says which environment rules measured the rows; rows from before a fix
    # that changed what is measured (eval_key.RULES_REVISION) must not mix into the table.
    source = tmp_path / "results"
    shutil.copytree(FIXTURE, source)
    (source / "M4" / "seed1" / "evaluation.json").write_text(json.dumps({"eval_key": "0123456789ab"}))
    (source / "M4" / "seed0" / "evaluation.json").write_text(json.dumps({"rules": RULES_REVISION}))
    assert report(tmp_path, "out", "--no-figures", source=source) == 0
    out = capsys.readouterr().out
    assert f"M4/seed1: evaluated under the environment's rules revision 1, not {RULES_REVISION}" in out
    summary = pd.read_csv(tmp_path / "out" / "summary.csv")
    assert set(summary.loc[summary["model"] == "M4", "n_seeds"]) == {1}


@pytest.mark.parametrize(
    ("setup", "message"),
    [
        (lambda root: None, "results folder not found"),
        (lambda root: root.mkdir(), "holds no run folders"),
        (lambda root: shutil.copytree(FIXTURE / "M0", root / "M1"), "holds rows of model M0, not M1"),
        (lambda root: (root / "M0" / "seed0").mkdir(parents=True)
         or (root / "M0" / "seed0" / "evaluation_rows.csv").write_text("model,seed\nM0,0\n"),
         "lack the column"),
    ],
)
def test_bad_folders_end_with_one_line(tmp_path, capsys, setup, message):
    source = tmp_path / "results"
    setup(source)
    assert report(tmp_path, "out", "--no-figures", source=source) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0]


def test_report_run_logged_to_mlflow(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    uri = f"sqlite:///{tmp_path}/mlflow.db"
    rc = main(["report", "--from", str(FIXTURE), "--no-figures", f"tracking.tracking_uri={uri}",
               "tracking.experiment=from-folder"])
    assert rc == 0
    assert (tmp_path / "reports" / "results" / "table.md").exists()  # default: reports/<folder name>
    client = MlflowClient(tracking_uri=uri)
    exp = client.get_experiment_by_name("from-folder")
    (run,) = client.search_runs([exp.experiment_id], filter_string="tags.kind = 'report'")
    assert run.info.status == "FINISHED" and run.data.tags["source"] == str(FIXTURE.resolve())
    assert {a.path for a in client.list_artifacts(run.info.run_id)} >= {"table.md", "improvement.csv"}
    assert "CS/CPM/M0" in run.data.metrics


def _corrupt(tmp_path: Path, edit) -> tuple[Path, Path]:
    """A copy of the fixture whose M4 seed1 rows file `edit` (text -> text) changed."""
    root = tmp_path / "results"
    shutil.copytree(FIXTURE, root)
    path = root / "M4" / "seed1" / "evaluation_rows.csv"
    path.write_text(edit(path.read_text()))
    return root, path


def _set(row: int, column: str, value: str):
    """Edit: the data row `row`'s `column` set to the text `value`."""
    def edit(text: str) -> str:
        frame = pd.read_csv(pd.io.common.StringIO(text), dtype=str, keep_default_na=False)
        frame.loc[row, column] = value
        return frame.to_csv(index=False)
    return edit


@pytest.mark.parametrize(("edit", "message"), [
    # killed while written: the last line cut inside the scenario name ("Int" of Intersection)
    (lambda t: t[: t.rindex(",Intersection,") + 4] + "\n", "unknown scenario 'Int'"),
    (_set(2, "CR_AA", "nan"), "CR_AA is not a finite number on line 4"),
    (_set(0, "CR_AL", ""), "CR_AL is not a finite number on line 2"),
    (_set(5, "CD", "inf"), "CD is not a finite number"),
    (_set(1, "CR_AA", "-0.1"), "CR_AA is not a rate in [0, 1]"),
    (_set(1, "CR_total", "1.5"), "CR_total is not a rate in [0, 1]"),
    (_set(3, "CR_total", "0.9"), "CR_total is not CR_AA + CR_AL on line 5"),
    (_set(4, "CD", "-2"), "CD (cm from the center line) is negative"),
    (_set(4, "AS", "3.0"), "AS (m/s) is not in [0, 0.8]"),
    (_set(4, "AS", "fast"), "AS is not a finite number"),
    (_set(0, "scenario", "Motorway"), "unknown scenario 'Motorway'"),
    (_set(0, "simulation", "1.5"), "simulation is not a whole number"),
    (lambda t: "garbage,header\n" + t.split("\n", 1)[1], "evaluation rows lack the column(s) scenario"),
])
def test_a_bad_rows_file_ends_in_one_line_naming_it(tmp_path, capsys, edit, message):
    root, path = _corrupt(tmp_path, edit)
    assert report(tmp_path, "out", "--no-figures", source=root) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and str(path) in err and message in err, err
    assert not (tmp_path / "out").exists()  # no report of the bad folder


def test_rows_as_written_pass_the_checks():
    # every committed study's rows, float32 sums and rounding included
    for root in (FIXTURE, Path(__file__).parents[1] / "results" / "paper-budget"):
        assert len(read_results(root).rows) > 0


@pytest.mark.parametrize("key", ["eval.scenarios", "study.scenarios"])
def test_scenarios_given_restrict_the_report_or_are_refused(tmp_path, capsys, key):
    assert report(tmp_path, "cpm", "--no-figures", f"{key}=[Roundabout,CPM]") == 0
    summary = pd.read_csv(tmp_path / "cpm" / "summary.csv")
    assert list(dict.fromkeys(summary["scenario"])) == ["CPM", "Roundabout"]  # the table's order
    full = pd.read_csv(FIXTURE / "M0" / "seed0" / "evaluation_rows.csv")
    assert set(full["scenario"]) - set(summary["scenario"]) == {"Intersection", "On-Ramp"}
    # a scenario the folder has no rows of: one line, no report
    capsys.readouterr()
    assert report(tmp_path, "none", "--no-figures", f"{key}=[CPM-30]") == 2
    assert "no evaluation rows of scenario(s) CPM-30" in capsys.readouterr().err
    assert not (tmp_path / "none").exists()


def test_a_report_of_other_columns_or_another_baseline_keeps_the_studys_folder(tmp_path, monkeypatch):
    from sigmarl.cli import main

    monkeypatch.chdir(tmp_path)
    common = ["report", "--from", str(FIXTURE), "--no-figures", "tracking.enabled=false"]
    assert main(common) == 0
    assert main([*common, "study.baseline=M4"]) == 0
    assert main([*common, "--models", "M4,M0", "study.baseline=M4"]) == 0
    assert sorted(p.name for p in (tmp_path / "reports").iterdir()) == [
        "results", "results_baseline-M4", "results_baseline-M4_models-M4+M0"]


def test_the_console_report_is_short_and_verbose_prints_the_full_text(tmp_path, capsys):
    # the short report: Table I's headline (CR_total, % of steps) as the table computes it, the
    # verdict counts as verdicts.csv holds them, where the files are; at most 40 lines
    assert report(tmp_path, "short", "--no-figures") == 0
    short = capsys.readouterr().out.rstrip("\n").splitlines()
    assert len(short) <= 40, len(short)
    rows = read_results(FIXTURE).rows
    seed_means = rows.groupby(["scenario", "model", "seed"])["CR_total"].mean().groupby(["scenario", "model"]).mean()
    for scenario in PAPER_SCENARIOS:
        line = next(x for x in short if x.startswith(f"| {scenario} |"))
        cells = [c.strip() for c in line.strip("|").split("|")[1:]]
        assert cells == [f"{100 * seed_means[(scenario, m)]:.2f}" for m in ("M0", "M4")], line
    verdicts = pd.read_csv(tmp_path / "short" / "verdicts.csv")["verdict"].value_counts()
    counts = next(x for x in short if x.startswith("verdicts,"))
    for verdict, n in verdicts.items():
        assert f"{n} {verdict}" in counts
    assert any(str(tmp_path / "short") in x for x in short)
    # --verbose: the whole table's text as before, its notes and the verdicts
    assert report(tmp_path, "long", "--no-figures", "--verbose") == 0
    full = capsys.readouterr().out
    assert (tmp_path / "long" / "table.md").read_text(encoding="utf-8").strip() in full
    assert len(full.splitlines()) > 40
