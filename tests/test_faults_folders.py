"""The fifth reliability round's file and folder faults (H5, H10-H15): each is one
line and exit code 2, naming what to fix, never a traceback, a hang or a silent choice."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest
from cli_errors import one_line_exit_2

from sigmarl.errors import MapError, SigmarlError
from sigmarl.maps.osm import load_osm
from sigmarl.readers import read_yaml

ROOT = Path(__file__).resolve().parents[1]


def _osm(path: Path, nodes: str, ways: str = "") -> Path:
    path.write_text(f"<?xml version='1.0'?>\n<osm version='0.6'>\n{nodes}{ways}</osm>\n")
    return path


NODES = "<node id='1' lat='50.0' lon='6.0'/><node id='2' lat='50.0' lon='6.00002'/>"
WAY = "<way id='7'><nd ref='1'/><nd ref='2'/><tag k='lanes' v='1'/></way>"


@pytest.mark.parametrize("extra, says", [
    ("<node id='2' lat='51.0' lon='6.0'/>", "node id 2 is given twice"),  # the last one silently won
    ("<way id='7'><nd ref='2'/><nd ref='1'/><tag k='lanes' v='2'/></way>", "way id 7 is given twice"),
])
def test_h5_an_osm_id_given_twice_is_refused_naming_it(tmp_path, extra, says):
    path = _osm(tmp_path / "twice.osm", NODES + (extra if "node" in extra else ""),
                WAY + (extra if "way" in extra else ""))
    with pytest.raises(MapError, match=says):
        load_osm(path)


@pytest.mark.parametrize("node, says", [
    ("<node id='2' lat='1e308' lon='6.0'/>", "node 2: lat='1e308' is outside [-90, 90]"),
    ("<node id='2' lat='50.0' lon='-1e308'/>", "node 2: lon='-1e308' is outside [-180, 180]"),
])
def test_h14_a_coordinate_beyond_the_globe_is_refused_naming_the_node(tmp_path, node, says, recwarn):
    path = _osm(tmp_path / "far.osm", "<node id='1' lat='50.0' lon='6.0'/>" + node, WAY)
    with pytest.raises(MapError, match=says.replace("[", r"\[").replace("]", r"\]")):
        load_osm(path)
    assert not [w for w in recwarn if "overflow" in str(w.message)]  # no numpy warnings first


def test_h14_local_coordinates_whose_differences_overflow_are_refused(tmp_path):
    nodes = ("<node id='1'><tag k='local_x' v='-1e308'/><tag k='local_y' v='0'/></node>"
             "<node id='2'><tag k='local_x' v='1e308'/><tag k='local_y' v='0'/></node>")
    with pytest.raises(MapError, match="node 1: local_x='-1e308' is outside"):
        load_osm(_osm(tmp_path / "far.osm", nodes, WAY))


def _bomb(depth: int) -> str:
    """A "billion laughs": each level nine aliases of the one before, 9**depth leaves."""
    lines = ["a0: &a0 [lol, lol, lol, lol, lol, lol, lol, lol, lol]"]
    lines += [f"a{k}: &a{k} [{', '.join([f'*a{k - 1}'] * 9)}]" for k in range(1, depth + 1)]
    return "variants:\n  A: [obs=full]\nbomb:\n" + "\n".join("  " + line for line in lines) + "\n"


def test_h13_yaml_aliases_are_refused_at_once(tmp_path):
    path = tmp_path / "bomb.yaml"
    path.write_text(_bomb(8))
    started = time.monotonic()
    with pytest.raises(SigmarlError, match=r"bomb.yaml, line 5: an alias \(\*a0\) is not allowed"):
        read_yaml(path)
    assert time.monotonic() - started < 5


@pytest.mark.parametrize("how", ["--config-dir", "SIGMARL_CONFIG_PATH"])
def test_h13_a_study_bomb_is_one_line_through_the_cli_under_a_timeout(tmp_path, how):
    """The old tree expanded depth 5 for 115 s and did not end at depth 8: a subprocess under
    a timeout, so that a regression fails instead of hanging the suite."""
    (tmp_path / "conf" / "study").mkdir(parents=True)
    (tmp_path / "conf" / "study" / "bomb.yaml").write_text(_bomb(8))
    argv = ["--config-dir", "conf"] if how == "--config-dir" else []
    env = {**os.environ, "SIGMARL_CONFIG_PATH": str(tmp_path / "conf") if how != "--config-dir" else ""}
    done = subprocess.run([sys.executable, "-m", "sigmarl", *argv, "sweep", "study=bomb", "tracking.enabled=false"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=120, env=env)
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 2 and len(lines) == 1 and "is not allowed" in lines[0], done.stderr[-500:]


def test_h10_maps_show_into_a_folder_that_cannot_be_one(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "afile").write_text("mine")
    line = one_line_exit_2(["maps", "show", "on_ramp", "--out", "afile/map.png"], capsys)
    assert "afile is not writable" in line and "--out" in line
    assert (tmp_path / "afile").read_text() == "mine"


def test_h10_report_out_into_a_folder_that_cannot_be_one(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "afile").write_text("mine")
    line = one_line_exit_2(["report", "--from", str(ROOT / "results" / "paper-budget"), "--no-figures",
                            "--out", "afile/report", "tracking.enabled=false"], capsys)
    assert "afile/report is not a folder the report can write" in line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile"]


def test_h12_a_cache_that_is_a_file_is_one_line(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "afile").write_text("mine")
    monkeypatch.setenv("SIGMARL_CACHE", str(tmp_path / "afile" / "sigmarl"))
    line = one_line_exit_2(["train", "ppo=smoke", "threads=1", "tracking.enabled=false"], capsys)
    assert "afile is a file, not a folder" in line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile"]


def test_h12_a_deleted_working_folder_is_one_line(tmp_path):
    gone = tmp_path / "gone"
    gone.mkdir()
    child = subprocess.Popen(["sh", "-c", f"cd {gone} && rmdir {gone} && exec {sys.executable} -m sigmarl train "
                              "ppo=smoke threads=1 tracking.enabled=false"], stderr=subprocess.PIPE, text=True)
    _, err = child.communicate(timeout=120)
    lines = err.strip().splitlines()
    assert child.returncode == 2 and len(lines) == 1 and "the working folder cannot be read" in lines[0], err[-500:]


@pytest.mark.parametrize("option, says", [
    (["--animations", "-5"], "--animations takes 1..10000 steps, got -5"),
    (["--models", ""], "--models needs comma-separated labels"),
    (["--models", "M0,,M4"], "--models needs comma-separated labels"),
])
def test_h15_reports_options_are_range_checked(option, says, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    line = one_line_exit_2(["report", "--from", str(ROOT / "results" / "paper-budget"), *option], capsys)
    assert says in line
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("made_anew", [False, True])
def test_h11_a_run_folder_deleted_during_training_is_one_line(tmp_path, made_anew):
    """The folder is removed once training has written its first iteration's metrics (and,
    as a checkpoint's write would, made anew: an empty folder is not the run's)."""
    child = subprocess.Popen([sys.executable, "-m", "sigmarl", "train", "ppo=smoke", "threads=1",
                              "tracking.enabled=false", "ppo.iterations=500", "run_dir=runs/x"],
                             cwd=tmp_path, stderr=subprocess.PIPE, text=True, env={**os.environ, "OMP_NUM_THREADS": "1"})
    metrics = tmp_path / "runs" / "x" / "metrics.csv"
    deadline = time.monotonic() + 120
    while not metrics.exists() and time.monotonic() < deadline and child.poll() is None:
        time.sleep(0.2)
    while (tmp_path / "runs" / "x").exists():  # the training may be writing a file into it meanwhile
        shutil.rmtree(tmp_path / "runs" / "x", ignore_errors=True)
    if made_anew:
        (tmp_path / "runs" / "x").mkdir(exist_ok=True)  # a checkpoint write may have made it already
    _, err = child.communicate(timeout=120)
    errors = [line for line in err.splitlines() if line.startswith("sigmarl")]
    assert child.returncode == 2, err[-800:]
    assert errors == ["sigmarl: error: runs/x: the run folder was deleted during training (its record ends FAILED); "
                      "train again to start over"]
    assert "Traceback" not in err
