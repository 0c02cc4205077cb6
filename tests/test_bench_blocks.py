"""benchmarks/bench_blocks.py: its table's arithmetic against hand-worked figures, and the
script itself at a tiny budget (S = 1, 2, one iteration) printing that table."""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "benchmarks" / "bench_blocks.py"


def _bench():
    spec = importlib.util.spec_from_file_location("bench_blocks", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_table_reads_per_seed_costs_against_one_seed() -> None:
    # one seed 2 s an iteration; a block of 4 at 4 s: 1 s per seed-iteration, half a seed alone;
    # at 250 iterations: one seed 3600 / 500 = 7.2 model-seeds per hour, the block 4 x 3600 / 1000
    result = {"device_type": "cpu", "paper_iterations": 250, "lone_s_per_iteration": 2.0,
              "rows": [{"S": 4, "s_per_iteration": 4.0, "s_per_seed_iteration": 1.0, "lone_s_per_iteration": 2.0,
                        "ratio_per_seed": 0.5, "model_seeds_per_hour": 14.4}, {"S": 8, "skipped": "out of memory"}]}
    lines = _bench().table(result).splitlines()
    assert lines[0] == ("| S | s per iteration | s per seed-iteration | one seed beside it, s | per seed vs one "
                        "| model-seeds per hour |")
    assert lines[2] == "| one seed | 2.00 | 2.00 | 2.00 | 1.00 | 7.20 |"
    assert lines[3] == "| 4 | 4.00 | 1.000 | 2.00 | 0.50 | 14.40 |"
    assert lines[4].startswith("| 8 | out of memory |")


def test_a_block_size_is_skipped_when_it_would_end_past_the_time_limit() -> None:
    bench = _bench()
    rows = [{"S": 8, "s_per_iteration": 10.0, "lone_s_per_iteration": 2.0}]
    # S = 64 at most 8x S = 8's 10 s: warm-up and one iteration 2 x 80 s, one lone iteration 2 s
    assert bench._estimate(rows, 64, 1) == 162.0
    assert bench._estimate([], 64, 1) == 0.0  # nothing measured yet: nothing to go by


@pytest.mark.slow
def test_the_script_times_one_seed_and_blocks_of_one_and_two(tmp_path) -> None:
    out = tmp_path / "bench.json"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT / "src"), os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.run([sys.executable, str(SCRIPT), "--sizes", "1", "2", "--iterations", "1", "--json", str(out),
                           "ppo=smoke"], capture_output=True, text=True, env=env, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    table = [line for line in proc.stdout.splitlines() if line.startswith("| ")]
    assert [line.split("|")[1].strip() for line in table] == ["S", "one seed", "1", "2"]
    result = json.loads(out.read_text())
    assert [r["S"] for r in result["rows"]] == [1, 2]
    for r in result["rows"]:
        assert r["s_per_iteration"] > 0
        assert r["s_per_seed_iteration"] == pytest.approx(r["s_per_iteration"] / r["S"])
        assert r["ratio_per_seed"] == pytest.approx(r["s_per_seed_iteration"] / r["lone_s_per_iteration"])
        assert sum(r["phases"].values()) == pytest.approx(r["s_per_iteration"])
