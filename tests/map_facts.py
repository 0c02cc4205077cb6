"""Checks shared by the map tests: a loaded map against the measured facts it was built from."""

from __future__ import annotations

import numpy as np


def assert_lanelets_are_the_facts(m, facts: dict) -> None:
    """Lanelet ids, center lines and successors as measured; boundaries the center line offset
    by +-w/2 along a unit left normal (so the lane is w wide and left is on the left)."""
    assert sorted(m.lanelets) == sorted(int(i) for i in facts["lanelets"])
    for lid, la in facts["lanelets"].items():
        got = m.lanelets[int(lid)]
        np.testing.assert_allclose(got.center, la["center"], atol=1e-9)
        assert got.successors == sorted(la["successors"])
        np.testing.assert_allclose(got.width, facts["lane_width"], atol=1e-12)
        across = got.left - got.right
        tangent = np.gradient(got.center, axis=0)
        assert np.all(tangent[:, 0] * across[:, 1] - tangent[:, 1] * across[:, 0] > 0)
