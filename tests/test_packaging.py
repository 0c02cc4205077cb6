"""The package as a user installs it: build sdist -> wheel, install the wheel alone into a
fresh venv outside the checkout, and run the CLI there.

The venv reaches the third-party dependencies through a .pth naming this interpreter's
site-packages (a full dependency install would take minutes); sigmarl itself is only the
wheel's copy: the .pth only appends a folder to sys.path, so the checkout's editable hook in
that folder is not run, and the test checks where `sigmarl` is imported from.
"""

from __future__ import annotations

import os
import subprocess
import sys
import sysconfig
import venv
import zipfile
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """(venv bin folder, clean env, work folder) with the freshly built wheel installed."""
    root = tmp_path_factory.mktemp("wheel")
    subprocess.run([sys.executable, "-m", "build", "--no-isolation", "-o", str(root / "dist"), str(REPO)],
                   check=True, capture_output=True)
    (wheel,) = (root / "dist").glob("sigmarl-*.whl")
    venv.create(root / "venv", with_pip=False)
    py = root / "venv" / "bin" / "python"
    purelib = subprocess.run([str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                             check=True, capture_output=True, text=True).stdout.strip()
    Path(purelib, "deps.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    # --ignore-installed: the checkout's editable sigmarl is visible through the .pth; it must
    # neither satisfy the request nor be uninstalled.
    subprocess.run([sys.executable, "-m", "pip", "--python", str(py), "install", "-q", "--no-deps",
                    "--ignore-installed", "--no-index", str(wheel)], check=True)
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "SIGMARL_CONF")}
    work = root / "work"
    work.mkdir()
    return wheel, root / "venv" / "bin", env, work


def test_wheel_ships_the_config_tree(installed):
    wheel = installed[0]
    names = zipfile.ZipFile(wheel).namelist()
    shipped = sorted(n.removeprefix("sigmarl/conf/") for n in names if n.startswith("sigmarl/conf/"))
    in_repo = sorted(str(p.relative_to(REPO / "conf")) for p in (REPO / "conf").rglob("*.yaml"))
    assert shipped == in_repo
    assert "sigmarl/data/paper_table_1.csv" in names
    # the paper's six policies (`sigmarl evaluate paper:M<k>`) travel with their licence notice
    policies = {f"sigmarl/data/paper_policies/M{k}_policy.pth" for k in range(6)}
    assert policies | {"sigmarl/data/paper_policies/LICENSE-SigmaRL.txt"} <= set(names)


def test_installed_cli_lists_maps_and_trains(installed):
    _, bin_dir, env, work = installed
    where = subprocess.run([str(bin_dir / "python"), "-c", "import sigmarl; print(sigmarl.__file__)"],
                           cwd=work, env=env, check=True, capture_output=True, text=True).stdout
    assert where.startswith(str(bin_dir.parent)) and str(REPO) not in where
    maps = subprocess.run([str(bin_dir / "sigmarl"), "maps", "list"], cwd=work, env=env,
                          capture_output=True, text=True)
    assert maps.returncode == 0, maps.stderr
    assert {"cpm", "cpm_intersection", "intersection", "on_ramp", "roundabout"} <= {
        line.split()[0] for line in maps.stdout.splitlines()[1:]}
    train = subprocess.run([str(bin_dir / "sigmarl"), "train", "ppo=smoke", "ppo.iterations=1"],
                           cwd=work, env=env, capture_output=True, text=True)
    assert train.returncode == 0, train.stderr[-2000:]
    assert list(work.glob("runs/*/*/seed0/final.pt"))
    assert (work / "mlflow.db").is_file()
