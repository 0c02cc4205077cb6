"""Probes of bad input: each must be one `sigmarl: error:` line naming what to fix, exit code 2,
and the probe's folder left exactly as it was (no run folder, no store, no changed file)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import probe_fixtures as fx
from probe_kit import SMOKE, TRACKERS, Probe, refusal

RESULTS = ["--from", "results"]


def _bad_yaml(folder: Path) -> None:
    (folder / "conf" / "study").mkdir(parents=True)
    (folder / "conf" / "study" / "mine.yaml").write_text("variants:\n  A: [obs=paper\n")


def _scenario(name: str, text: str):
    def setup(folder: Path) -> None:
        (folder / "conf" / "scenario").mkdir(parents=True)
        (folder / "conf" / "scenario" / f"{name}.yaml").write_text(text)
    return setup


def _looping_forks(folder: Path) -> None:
    """An OpenStreetMap file of 22 forks whose last hub loops back: 2^22 paths and no exit, so
    route enumeration must stop at its bound rather than run for hours."""
    nodes, ways = {}, {9: [122, 100]}
    for j in range(22):
        nodes.update({100 + j: (2.0 * j, 0.0), 200 + j: (2.0 * j + 1, 0.5), 300 + j: (2.0 * j + 1, -0.5)})
        ways[10 + 2 * j], ways[11 + 2 * j] = [100 + j, 200 + j, 101 + j], [100 + j, 300 + j, 101 + j]
    nodes[122] = (44.0, 0.0)
    body = "".join(f"<node id='{i}' lat='{50 + x * 1e-5!r}' lon='{6 + y * 1e-5!r}'/>" for i, (x, y) in nodes.items())
    body += "".join(f"<way id='{w}'>" + "".join(f"<nd ref='{r}'/>" for r in refs) + "<tag k='lanes' v='1'/></way>"
                    for w, refs in ways.items())
    (folder / "forks.osm").write_text(f"<?xml version='1.0'?>\n<osm version='0.6'>\n{body}\n</osm>\n")


def _duplicated_row(folder: Path) -> None:
    path = fx.results_copy(folder) / "M0" / "seed1" / "evaluation_rows.csv"
    lines = path.read_text().splitlines(keepends=True)
    path.write_text("".join([*lines, lines[5]]))


def _damaged_metrics_cell(folder: Path) -> None:
    path = fx.results_copy(folder) / "M4" / "seed1" / "metrics.csv"
    lines = path.read_text().splitlines(keepends=True)
    header = lines[0].rstrip("\n").split(",")
    cells = lines[2].rstrip("\n").split(",")
    cells[header.index("episode_reward_mean")] = "abc"
    lines[2] = ",".join(cells) + "\n"
    path.write_text("".join(lines))


def _seeds_auto_record(folder: Path) -> None:
    (folder / "runs").mkdir()
    (folder / "runs" / "seeds_auto.json").write_text('["M0/seed0"]')


def _tracker(folder: Path) -> None:
    (folder / "refusing_tracker.py").write_text(TRACKERS)


def _evaluate_whole(override: str):
    """`evaluate` of the uninterrupted fixture's best.pt with an override it cannot honour."""
    def check(folder: Path) -> str | None:
        fx.copy_of(fx.whole)(folder)
        return refusal(["evaluate", str(fx.RUN / "best.pt"), override, "eval.n_sims=1", "tracking.enabled=false"],
                       f"evaluate cannot honour {override}")(folder)
    return check


def _experiment_names(folder: Path) -> str | None:
    for name in (".hidden", "-rf"):
        wrong = refusal(["train", *SMOKE, f"tracking.experiment='{name}'"], "tracking.experiment=")(folder)
        if wrong:
            return f"{name}: {wrong}"
    return None


def _exact_names(folder: Path) -> str | None:
    """`probe.py F1` must select F1's probe alone, not F11's and F12's (a substring match did)."""
    script = Path(__file__).with_name("probe.py")
    for word, want in (("F1", ["F1-experiment"]), ("F6", ["F6-scenario-agents", "F6-train-agents"])):
        done = subprocess.run([sys.executable, str(script), "--list", word], capture_output=True, text=True,
                              timeout=60)
        if done.stdout.split() != want:
            return f"`probe.py --list {word}` selects {done.stdout.split()}, not {want}"
    return None


PROBES = [
    Probe("unknown-key", "a misspelt key", refusal(["train", *SMOKE, "ppo.epoch=3"], "ppo.epochs")),
    Probe("F1-experiment", "an experiment name that leaves the runs folder",
          refusal(["train", *SMOKE, "tracking.experiment=../../etc"], "tracking.experiment")),
    Probe("F2-seeds", "a seed that is not a whole number",
          refusal(["sweep", "study=quick", "models=[M0]", "seeds=[abc]", "tracking.enabled=false"], "seed")),
    Probe("F3-nan", "NaN as a learning rate", refusal(["train", *SMOKE, "ppo.lr=nan"], "ppo.lr")),
    Probe("F4-yaml", "a syntax error in a --config-dir",
          refusal(["--config-dir", "conf", "train", *SMOKE], "mine.yaml", _bad_yaml)),
    Probe("F5-map", "a user's scenario naming a map that does not exist",
          refusal(["--config-dir", "conf", "train", *SMOKE, "eval.scenarios=[Lost]"], "'nowhere'",
                  _scenario("Lost", "map: nowhere\nn_agents: 4\n"))),
    Probe("F6-scenario-agents", "a user's scenario of more agents than its map holds",
          refusal(["--config-dir", "conf", "sweep", "study=quick", "models=[M0]", *SMOKE, "eval.scenarios=[Crowd]"],
                  "at most 87", _scenario("Crowd", "map: paper_roundabout\nn_agents: 10000\n"))),
    Probe("F6-train-agents", "training more agents than the map holds",
          refusal(["train", *SMOKE, "env.n_agents=10000"], "at most 344")),
    Probe("F7-routes", "a map whose forks loop back without an exit (2^22 paths)",
          refusal(["train", *SMOKE, "map.kind=osm", "map.path=forks.osm"], "forks.osm", _looping_forks)),
    Probe("F8-rows", "an evaluation row given twice in a results folder",
          refusal(["report", *RESULTS, "--plan"], "twice", _duplicated_row)),
    Probe("F9-seeds-auto", "a seeds=auto record of the wrong shape",
          refusal(["sweep", "seeds=auto", "models=[M0,M4]", "study.seeds=[0,1]", "tracking.enabled=false",
                   "runs_root=runs"], "seeds_auto.json", _seeds_auto_record)),
    Probe("F14-tracker-start", "a user's tracker that fails when it is made",
          refusal(["train", *SMOKE, "tracking.enabled=true", "tracking.backend=refusing_tracker:Refuses"],
                  "no token", _tracker)),
    Probe("G4-metrics-cell", "a non-number in a results folder's metrics.csv",
          refusal(["report", *RESULTS, "--no-figures", "--out", "out", "tracking.enabled=false"],
                  "metrics.csv: line 3: episode_reward_mean 'abc' is not a number", _damaged_metrics_cell)),
    Probe("G5-auto-empty", "seeds=auto for a study of its baseline alone",
          refusal(["sweep", "seeds=auto", "study=quick", "models=[M0]", "study.seeds=[0,1]", "tracking.enabled=false",
                   "runs_root=runs"], "nothing to compare")),
    Probe("G7-exact-names", "a probe chosen by its fault's name runs that fault's probes only", _exact_names),
    Probe("G8-no-metric", "a seed plan over no metric",
          refusal(["report", *RESULTS, "--plan", "study.metrics=[]"], "study.metrics is empty", fx.results_copy)),
    Probe("G9-evaluate-override", "evaluate with a training override it would drop",
          _evaluate_whole("obs=no_ego_view"), trains=True),
    Probe("G10-experiment-name", "experiment names `.hidden` and `-rf`", _experiment_names),
    Probe("G11-plan-paths", "a seed plan's error names its folders as typed",
          refusal(["report", *RESULTS, "--plan", "--models", "M4"], "from results are M4", fx.results_copy)),
]
