"""What makes two evaluations interchangeable: the protocol (scenarios with their maps and
agents, simulations, steps, seed, checkpoint, and the revision of the environment's rules that
measured them). Not the metric columns they hold. Light to import: a sweep's plan checks it."""

from __future__ import annotations

import hashlib
import json

from sigmarl.config import EvalConfig, as_dict
from sigmarl.scenarios import scenario, scenario_names

# Revision of how the environment measures. Bump it when a fix changes collision flags or
# metrics, so that rows measured under older rules are redone rather than reused.
# 2: lane contacts "beyond the boundary" decided by crossing parity (the nearest-segment side
# test gave false contacts on CPM).
RULES_REVISION = 2


def protocol(eval_cfg: EvalConfig) -> dict:
    """The evaluation protocol, defined once: the scenarios (with their maps and agents), the
    simulations, steps, seed and checkpoint, and the rules revision that measures them. Not the
    metric columns: a metric added later leaves every stored row file in its protocol."""
    described = as_dict(eval_cfg)
    # A scenario's name does not say which map it ran on (Table I's names moved from the
    # procedural maps to the paper's own): the protocol holds each scenario's map and agents.
    known = scenario_names()
    described["maps"] = {s: [scenario(s).map, scenario(s).n_agents] for s in described["scenarios"] if s in known}
    described["rules"] = RULES_REVISION
    return described


def protocol_key(eval_cfg: EvalConfig) -> str:
    """A short hash of the protocol (`protocol`): what tells a study's evaluation from a one-off."""
    return _hash(protocol(eval_cfg))


def eval_key(eval_cfg: EvalConfig) -> str:
    """The key rows are stored and reused under: the protocol's (`protocol_key`). The metric
    columns are not part of it: a metric declared later leaves every stored key as it was, and
    rows without its column read "not measured" (`sigmarl evaluate --add-metrics` measures it)."""
    return protocol_key(eval_cfg)


def _hash(described: dict) -> str:
    return hashlib.sha1(json.dumps(described, sort_keys=True).encode()).hexdigest()[:12]
