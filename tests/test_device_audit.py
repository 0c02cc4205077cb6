"""The GPU path without a GPU: every tensor that sigmarl's own code creates while the
environment steps, the networks act, the loss trains and an evaluation rolls out must be made
on the configured device. A tensor made without `device=` lands on the CPU: on CPU that goes
unnoticed, with device=cuda it is a device mismatch or a host round trip every step. The audit
(a TorchFunctionMode) records every torch factory call made directly from sigmarl's source and
fails on any that names no device (and on any float64 result).

Building the route tables is left out on purpose: they are computed with numpy on the CPU and
moved to the device once (`RouteBank.__init__`); the meta-device test checks that move."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
import torch
from torch.overrides import TorchFunctionMode

import sigmarl
from sigmarl.compose import compose_config
from sigmarl.env.route_bank import RouteBank
from sigmarl.evaluation.rollout import evaluate_policy
from sigmarl.maps import load_map, map_config
from sigmarl.training.learner import Learner
from sigmarl.training.mappo import collect, update

SRC = str(Path(sigmarl.__file__).resolve().parent)
ROUTE_BANK = f"{SRC}/env/route_bank.py"
FACTORIES = {torch.zeros, torch.ones, torch.empty, torch.full, torch.arange, torch.linspace,
             torch.tensor, torch.as_tensor, torch.rand, torch.randn, torch.randint, torch.eye,
             torch.randperm, torch.from_numpy, torch.logspace, torch.empty_strided}


def _building_tables(frame) -> bool:
    """Inside RouteBank's constructor or the map code (CPU by design, checked below)."""
    while frame is not None:
        name = frame.f_code.co_filename
        if name.startswith(f"{SRC}/maps/") or (name == ROUTE_BANK and frame.f_code.co_name == "__init__"):
            return True
        frame = frame.f_back
    return False


class FactoryAudit(TorchFunctionMode):
    """Records (file:line, function) of factory calls from sigmarl without a device."""

    def __init__(self) -> None:
        super().__init__()
        self.found: set[tuple[str, str]] = set()
        self.dtypes: set[tuple[str, torch.dtype]] = set()

    def __torch_function__(self, func, types, args=(), kwargs=None):
        kwargs = kwargs or {}
        out = func(*args, **kwargs)
        frame = sys._getframe(1)
        if frame.f_code.co_filename.startswith(SRC) and not _building_tables(frame):
            where = f"{Path(frame.f_code.co_filename).relative_to(SRC)}:{frame.f_lineno}"
            derived = func in (torch.tensor, torch.as_tensor) and args and isinstance(args[0], torch.Tensor)
            if func in FACTORIES and kwargs.get("device") is None and not derived:
                self.found.add((where, func.__name__))
            if isinstance(out, torch.Tensor) and out.dtype == torch.float64:
                self.dtypes.add((where, func.__name__ if hasattr(func, "__name__") else str(func)))
        return out


@pytest.fixture(scope="module")
def parts():
    cfg = compose_config(["tracking.enabled=false", "ppo=smoke", "ppo.num_envs=4",
                          "ppo.frames_per_iteration=256", "ppo.minibatch_size=64",
                          "network.hidden=[16,16]"])
    built = Learner(cfg, [cfg.seed], torch.device(cfg.device))
    yield cfg, built
    built.close()


def test_no_tensor_of_a_training_iteration_skips_the_device(parts):
    cfg, p = parts
    batches = iter(p.collector)
    p.reseed(0)  # the generators, seeded per iteration
    audit = FactoryAudit()
    with audit:
        data = p.advantage(collect(batches))  # env resets (partial and full), steps, the sampler, GAE
        update(data, p.loss, p.optimiser, cfg.ppo)
    assert not sorted(audit.found), "factory calls without device=: " + str(sorted(audit.found))
    assert not sorted(audit.dtypes), "float64 tensors: " + str(sorted(audit.dtypes))


@pytest.mark.parametrize("name", ["cpm", "roundabout"])
def test_route_tables_end_on_the_configured_device(name):
    """Built on the CPU, every table must move: on the `meta` device (no data, any device
    mismatch shows) nothing may be left on the CPU, and floats are float32."""
    road_map = load_map(map_config(name))
    bank = RouteBank(road_map, torch.device("meta"))
    tensors = {k: v for k, v in vars(bank).items() if isinstance(v, torch.Tensor)}
    assert len(tensors) >= 10
    assert {k: v.device.type for k, v in tensors.items() if v.device.type != "meta"} == {}
    assert {k: v.dtype for k, v in tensors.items() if v.is_floating_point() and v.dtype != torch.float32} == {}


def test_no_tensor_of_an_evaluation_rollout_skips_the_device(parts):
    """Test-mode rollouts (respawns, metrics on the fly); the scenario's map tables are built
    inside, so the construction-only modules are left to the test above."""
    cfg, p = parts
    actor, _ = p.networks(0)  # the seed's ProbabilisticActor, as a checkpoint loads it
    audit = FactoryAudit()
    with audit:
        evaluate_policy(actor, cfg, "Roundabout", n_sims=2, steps=30, n_agents=cfg.env.n_agents,
                        progress=False)
    assert not sorted(audit.found), "factory calls without device=: " + str(sorted(audit.found))
    assert not sorted(audit.dtypes), "float64 tensors: " + str(sorted(audit.dtypes))
