"""Probes of the fifth round's config values, files and folders (issue 59: H2, H5-H15): each
must be one `sigmarl: error:` line, exit code 2, and (where nothing ran yet) the probe's folder
left exactly as it was: no run folder, no MLflow store.

On a tree without these checks, H2 spawns a million threads and H7 and H13 try to fill memory:
run such a tree's probes only under `ulimit -u` and `ulimit -v` (docs/reliability.md)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

from probe_fixtures import RESULTS
from probe_kit import SIGMARL, SMOKE, Probe, env, one_line, refusal, start

# the refusal must come before an MLflow store exists, so the round's own store is on
STORED = [*SMOKE, "tracking.enabled=true", "tracking.tracking_uri=sqlite:///mlflow.db"]
TWICE = ("<node id='1' lat='50.0' lon='6.0'/><node id='2' lat='50.0' lon='6.00002'/>"
         "<node id='2' lat='51.0' lon='6.0'/>")
FAR = "<node id='1' lat='50.0' lon='6.0'/><node id='2' lat='1e308' lon='6.0'/>"
WAY = "<way id='7'><nd ref='1'/><nd ref='2'/><tag k='lanes' v='1'/></way>"


def _osm(nodes: str):
    def setup(folder: Path) -> None:
        (folder / "map.osm").write_text(f"<?xml version='1.0'?>\n<osm version='0.6'>\n{nodes}{WAY}</osm>\n")
    return setup


def _bomb(folder: Path) -> None:
    """A 1 kB study of nine aliases a level, eight levels deep: 9**8 leaves once expanded."""
    lines = ["a0: &a0 [lol, lol, lol, lol, lol, lol, lol, lol, lol]"]
    lines += [f"a{k}: &a{k} [{', '.join([f'*a{k - 1}'] * 9)}]" for k in range(1, 9)]
    (folder / "conf" / "study").mkdir(parents=True)
    (folder / "conf" / "study" / "bomb.yaml").write_text("variants:\n  A: [obs=full]\nbomb:\n"
                                                         + "".join(f"  {line}\n" for line in lines))


def _a_file(folder: Path) -> None:
    (folder / "afile").write_text("mine\n")


def _bomb_in_time(folder: Path) -> str | None:
    """The bomb through `--config-dir`, under a timeout: the old tree did not end in 300 s."""
    _bomb(folder)
    try:
        done = subprocess.run([*SIGMARL, "--config-dir", "conf", "sweep", "study=bomb", "tracking.enabled=false"],
                              cwd=folder, capture_output=True, text=True, timeout=60, env=env())
    except subprocess.TimeoutExpired:
        return "no answer within 60 s: the aliases are being expanded"
    return one_line(done, "is not allowed")


def _deleted_run_folder(folder: Path) -> str | None:
    """The run folder removed once its first iteration is written: one line, no traceback."""
    child = start(["train", *SMOKE, "ppo.iterations=500", "run_dir=runs/x"], folder)
    run = folder / "runs" / "x"
    deadline = time.monotonic() + 120
    while not (run / "metrics.csv").exists() and time.monotonic() < deadline and child.poll() is None:
        time.sleep(0.2)
    while run.exists():  # the training may be writing into it meanwhile
        shutil.rmtree(run, ignore_errors=True)
    try:
        _, err = child.communicate(timeout=120)
    except subprocess.TimeoutExpired:
        child.kill()
        return "the training went on without its run folder for 120 s"
    said = [line for line in err.splitlines() if line.startswith("sigmarl")]
    if child.returncode != 2 or "Traceback" in err or len(said) != 1 or "was deleted during training" not in said[0]:
        return f"rc {child.returncode}: {(said or err.splitlines() or ['(nothing)'])[-1][:200]}"
    return None


def _gone_working_folder(folder: Path) -> str | None:
    gone = folder / "gone"
    gone.mkdir()
    done = subprocess.run(["sh", "-c", f"cd '{gone}' && rmdir '{gone}' && exec \"$0\" -m sigmarl train "
                           "ppo=smoke threads=1 tracking.enabled=false", sys.executable],
                          capture_output=True, text=True, timeout=120, env=env())
    return one_line(done, "the working folder cannot be read")


def _cache_is_a_file(folder: Path) -> str | None:
    _a_file(folder)
    done = subprocess.run([*SIGMARL, "train", *STORED], cwd=folder, capture_output=True, text=True, timeout=120,
                          env=env(SIGMARL_CACHE=str(folder / "afile")))
    return one_line(done, "is a file, not a folder")


def _beyond_this_machine(folder: Path) -> str | None:
    threads = 4 * (os.cpu_count() or 1) + 1
    if threads > 1024:
        return None  # the schema's own cap answers first (H2-threads)
    return refusal(["train", *STORED, f"threads={threads}"], "CPUs of this machine")(folder)


REPORT = ["report", "--from", str(RESULTS)]

PROBES = [
    Probe("H2-threads", "threads=1000000 (it spawned threads until the machine ran out of process ids)",
          refusal(["train", *STORED, "threads=1000000"], "threads must be in 1..1024")),
    Probe("H2-cores", "threads beyond 4 x the CPUs of the machine the work runs on", _beyond_this_machine),
    Probe("H5-osm-ids", "an OSM node id given twice (the last one silently won)",
          refusal(["train", *STORED, "map.kind=osm", "map.path=map.osm"], "node id 2 is given twice", _osm(TWICE))),
    Probe("H6-gamma", "ppo.gamma=2 ppo.lmbda=3 (trained to losses near 1e14)",
          refusal(["train", *STORED, "ppo.gamma=2", "ppo.lmbda=3"], "ppo.gamma must be in [0, 1]")),
    Probe("H7-frames", "ppo.frames_per_iteration=10**12", refusal(["train", *STORED, "ppo.frames_per_iteration="
                                                                   "1000000000000"], "ppo.frames_per_iteration")),
    Probe("H7-hidden", "network.hidden=[100000,100000]",
          refusal(["train", *STORED, "network.hidden=[100000,100000]"], "network.hidden must be in 1..65536")),
    Probe("H7-memory", "network.hidden=[65536,65536,65536]: within the caps, beyond memory",
          refusal(["train", *STORED, "network.hidden=[65536,65536,65536]"], "GiB free here")),
    Probe("H8-clip", "ppo.clip_epsilon=1 (\"math domain error\")",
          refusal(["train", *STORED, "ppo.clip_epsilon=1"], "ppo.clip_epsilon must be in (0, 1)")),
    Probe("H9-cuda", "device=cuda:abc", refusal(["train", *STORED, "device=cuda:abc"], "device='cuda:abc'")),
    Probe("H9-cpu", "device=cpu:abc", refusal(["train", *STORED, "device=cpu:abc"], "device='cpu:abc'")),
    Probe("H10-maps-out", "maps show --out into a folder that is a file",
          refusal(["maps", "show", "on_ramp", "--out", "afile/map.png"], "afile is not writable", _a_file)),
    Probe("H10-report-out", "report --out into a folder that is a file",
          refusal([*REPORT, "--no-figures", "--out", "afile/report", "tracking.enabled=false"],
                  "is not a folder the report can write", _a_file)),
    Probe("H11-deleted-run", "the run folder deleted during training", _deleted_run_folder, trains=True),
    Probe("H12-cache", "SIGMARL_CACHE naming a file", _cache_is_a_file),
    Probe("H12-cwd", "a deleted working folder", _gone_working_folder),
    Probe("H13-yaml-bomb", "a 1 kB study of nested YAML aliases (a billion laughs)", _bomb_in_time),
    Probe("H14-osm-far", "an OSM coordinate of 1e308",
          refusal(["train", *STORED, "map.kind=osm", "map.path=map.osm"], "lat='1e308' is outside", _osm(FAR))),
    Probe("H15-animations", "report --animations -5", refusal([*REPORT, "--animations", "-5"], "--animations")),
    Probe("H15-models", "report --models ''", refusal([*REPORT, "--models", ""], "--models needs")),
]
