"""The route bank's per-point tables (`follow_line`, `_local_runs`) against a plain
element-by-element walk of the same rules, on every map config and on random lines."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from sigmarl.env.collision import segment_table
from sigmarl.env.route_bank import (
    RouteBank,
    _local_runs,
    _stack_lines,
    follow_line,
    reaches,
    segment_distances,
)
from sigmarl.maps import load_map, map_config


def _step(j: int, k: int, n: int, loop: bool) -> int:
    return (j + k) % n if loop else min(max(j + k, 0), n - 1)


def follow_walk(d: np.ndarray, n_line, n_center, is_loop, ahead: int = 8) -> np.ndarray:
    """Each center point takes the nearest of the previous point's element and the `ahead`
    after it (the first of equally near ones); padding rows repeat the last real one."""
    r_n, c_n, m_n, _ = d.shape
    out = np.zeros((r_n, c_n, m_n), dtype=np.int64)
    for r in range(r_n):
        for c in range(c_n):
            n, j = int(n_line[r, c]), 0
            for i in range(int(n_center[r])):
                j = min((_step(j, k, n, bool(is_loop[r])) for k in range(ahead + 1)), key=lambda q: d[r, c, i, q])
                out[r, c, i] = j
            out[r, c, int(n_center[r]):] = j
    return out


def runs_walk(d: np.ndarray, near, n_seg, is_loop, reach: float) -> np.ndarray:
    """Grow each run from `near` one segment at a time, backwards then forwards, while the next
    segment is within reach, is not in the run yet and the run is shorter than the line."""
    r_n, c_n, m_n, _ = d.shape
    runs = {}
    for r in range(r_n):
        for c in range(c_n):
            n = int(n_seg[r, c])
            for i in range(m_n):
                run = [int(near[r, c, i])]
                for direction in (-1, 1):
                    j = run[0] if direction < 0 else run[-1]
                    while len(run) < n:
                        nxt = _step(j, direction, n, bool(is_loop[r]))
                        if nxt == j or nxt in run or d[r, c, i, nxt] > reach:
                            break
                        run.insert(0, nxt) if direction < 0 else run.append(nxt)
                        j = nxt
                runs[r, c, i] = run
    width = max(len(run) for run in runs.values())
    out = np.zeros((r_n, m_n, c_n, width), dtype=np.int64)
    for (r, c, i), run in runs.items():
        out[r, i, c] = run + [run[-1]] * (width - len(run))
    return out


def check(dist: torch.Tensor, n_line: torch.Tensor, n_center: torch.Tensor, is_loop: torch.Tensor) -> None:
    near = follow_line(dist, n_line, n_center, is_loop)
    np.testing.assert_array_equal(near.numpy(), follow_walk(dist.numpy(), n_line, n_center, is_loop))
    for reach in (0.05, 0.4, 1.5):
        got = _local_runs(dist, near, n_line, is_loop, reach).numpy()
        np.testing.assert_array_equal(got, runs_walk(dist.numpy(), near.numpy(), n_line, is_loop, reach))


@pytest.mark.parametrize("name", ["cpm", "cpm_intersection", "paper_intersection", "paper_on_ramp",
                                  "paper_roundabout", "intersection", "on_ramp", "roundabout"])
def test_tables_of_every_map(name):
    routes = load_map(map_config(name)).routes
    lines, n_lines = _stack_lines([[r.center] for r in routes])
    bounds, n_bounds = _stack_lines([[r.left, r.right] for r in routes])
    is_loop = torch.tensor([r.is_loop for r in routes])
    seg_dist = segment_distances(lines[:, 0], segment_table(bounds))
    check(seg_dist, n_bounds - 1, n_lines[:, 0], is_loop)


@pytest.mark.parametrize("seed", range(6))
def test_tables_of_random_lines(seed):
    """Distances with ties, lines of one element, loops and open lines, short center lines."""
    g = np.random.default_rng(seed)
    r_n, c_n, m_n, s_n = 4, 2, 15, 9
    dist = torch.from_numpy(g.integers(0, 8, (r_n, c_n, m_n, s_n)) * 0.25)
    n_line = torch.from_numpy(g.integers(1, s_n + 1, (r_n, c_n)))
    n_center = torch.from_numpy(g.integers(1, m_n + 1, r_n))
    check(dist, n_line, n_center, torch.tensor([True, False, True, False]))


def test_bank_reaches_use_the_runs():
    bank = RouteBank(load_map(map_config("paper_intersection")))
    assert (bank.reach, bank.wide_reach) == reaches(bank.extent)
