"""Shared fixtures of the environment tests: hand-computable road maps and an env driver.

The straight road is two lanelets along the x axis, x in [0, 2] and [2, 4], with the left
boundary at y = +half_width and the right one at y = -half_width. Its route "straight" has
the center line y = 0 resampled every 0.08 m (point k at x = 0.08 k, k = 0..50; then the
straight extension x = 4.08 .. 4.64), so every distance and look-ahead point in the
environment tests can be worked out by hand.
"""

from __future__ import annotations

import os

if os.environ.get("PYTEST_XDIST_WORKER"):
    # One thread per worker (and per subprocess it starts): two workers on two cores with
    # torch's default threads each contend for the cores and run slower than one worker.
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    os.environ.setdefault("MKL_NUM_THREADS", "1")

import functools
from types import SimpleNamespace

import numpy as np
import pytest
import torch
from torchrl.envs.utils import step_mdp

from sigmarl.compose import compose_config
from sigmarl.env.factory import make_env
from sigmarl.maps.model import Lanelet, RoadMap
from sigmarl.maps.routes import build_route

if os.environ.get("PYTEST_XDIST_WORKER"):
    torch.set_num_threads(1)  # in case a plugin imported torch before the lines above ran

ROAD_LENGTH = 4.0


def straight_road_map(half_width: float = 0.075, length: float = ROAD_LENGTH) -> RoadMap:
    """A one-route straight road along +x with boundaries at y = +-half_width."""

    def lanelet(lid: int, x0: float, x1: float, succ: list[int], pred: list[int]) -> Lanelet:
        x = np.linspace(x0, x1, 11)
        return Lanelet(
            lid,
            left=np.stack([x, np.full_like(x, half_width)], 1),
            right=np.stack([x, np.full_like(x, -half_width)], 1),
            successors=succ,
            predecessors=pred,
        )

    half = length / 2
    lanelets = {1: lanelet(1, 0.0, half, [2], []), 2: lanelet(2, half, length, [], [1])}
    route = build_route("straight", [1, 2], lanelets)
    return RoadMap("straight", lanelets, [route], lane_width=2 * half_width, source="tests")


@functools.cache
def _cfg(overrides: tuple[str, ...]):
    return compose_config(list(overrides))


class Driver:
    """A torchrl env plus its scenario, with helpers to place agents and step by hand."""

    def __init__(self, env):
        self.env = env
        self.sc = env.scenario
        self.n_envs = env.batch_size[0]
        self.n_agents = self.sc.n_agents
        self.td = env.reset()

    def place(self, pos, heading, speed=None, steering=None, route=None) -> torch.Tensor:
        """set_state with plain lists/tensors ([E, A] or [A] broadcast over envs)."""
        pos = torch.as_tensor(pos, dtype=torch.float32)
        heading = torch.as_tensor(heading, dtype=torch.float32)
        if route is None:
            route = torch.zeros(heading.shape, dtype=torch.long)
        speed = None if speed is None else torch.as_tensor(speed, dtype=torch.float32)
        steering = None if steering is None else torch.as_tensor(steering, dtype=torch.float32)
        return self.sc.set_state(torch.as_tensor(route), pos, heading, speed, steering)

    def step(self, action):
        """One env.step with action [E, A, 2] (or [A, 2] / [2], broadcast); returns td["next"]."""
        a = torch.as_tensor(action, dtype=torch.float32).expand(self.n_envs, self.n_agents, 2)
        self.td["agents", "action"] = a.clone()
        out = self.env.step(self.td)
        nxt = out["next"]
        self.td = step_mdp(out)
        return nxt


@pytest.fixture(scope="session", autouse=True)
def store_template_cache(tmp_path_factory) -> None:
    """The suite's own cache of the empty MLflow store (inherited by the commands it starts),
    so that it neither reads nor writes the user's ~/.cache."""
    os.environ["SIGMARL_CACHE"] = str(tmp_path_factory.mktemp("sigmarl-cache"))


@pytest.fixture(autouse=True)
def own_config_folders_end_with_the_test():
    """`sigmarl --config-dir DIR` adds DIR to $SIGMARL_CONFIG_PATH for the rest of the process
    (so a sweep's jobs inherit it); in the suite, it must not outlive the test that typed it."""
    from sigmarl.paths import CONFIG_PATH

    before = os.environ.get(CONFIG_PATH)
    yield
    if before is None:
        os.environ.pop(CONFIG_PATH, None)
    else:
        os.environ[CONFIG_PATH] = before


@pytest.fixture(scope="session")
def straight_road() -> RoadMap:
    return straight_road_map(0.075)


@pytest.fixture(scope="session")
def wide_road() -> RoadMap:
    """Same straight road, 2 m wide: room to drive circles without touching a boundary."""
    return straight_road_map(1.0)


@pytest.fixture(scope="session")
def env_factory():
    """make(overrides, **make_env kwargs) -> Driver; obs.noise defaults to 0."""

    def make(overrides=(), **kwargs) -> Driver:
        ov = tuple(overrides)
        if not any(o.startswith("obs.noise=") for o in ov):
            ov = ("obs.noise=0", *ov)
        n = kwargs.get("n_agents")
        if n is not None and not any(o.startswith("obs.n_nearest=") for o in ov):
            ov = (f"obs.n_nearest={min(2, n - 1)}", *ov)  # as many neighbours as there are, up to 2
        return Driver(make_env(_cfg(ov), **kwargs))

    return make


@pytest.fixture(scope="session")
def kit():
    return SimpleNamespace(straight_road_map=straight_road_map, cfg=_cfg)
