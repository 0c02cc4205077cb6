"""What makes two evaluations interchangeable: the protocol (scenarios with their maps and
agents, simulations, steps, seed, checkpoint), the revision of the environment's rules that
measured them, and the metric columns they hold. Light to import: a sweep's plan checks it."""

from __future__ import annotations

import hashlib
import json

from sigmarl.config import EvalConfig, as_dict
from sigmarl.metrics import METRIC_COLUMNS
from sigmarl.scenarios import scenario, scenario_names

# Revision of how the environment measures. Bump it when a fix changes collision flags or
# metrics, so that rows measured under older rules are redone rather than reused.
# 2: lane contacts "beyond the boundary" decided by crossing parity (the nearest-segment side
# test gave false contacts on CPM).
RULES_REVISION = 2
# The metric columns rows of this revision hold. Keys of rows with just these leave them out of
# the hash (as every key did before the metrics were hashed), so the evaluations stored so far
# keep their keys; a metric added since changes every key by itself, no revision bump needed.
REVISION_METRICS = ("CR_AA", "CR_AL", "CR_total", "CD", "AS")


def eval_key(eval_cfg: EvalConfig) -> str:
    """A short hash of the evaluation protocol: runs with equal keys are interchangeable."""
    protocol = as_dict(eval_cfg)
    # A scenario's name does not say which map it ran on (Table I's names moved from the
    # procedural maps to the paper's own): the key holds each scenario's map and agents.
    known = scenario_names()
    protocol["maps"] = {s: [scenario(s).map, scenario(s).n_agents] for s in protocol["scenarios"] if s in known}
    protocol["rules"] = RULES_REVISION
    if tuple(METRIC_COLUMNS) != REVISION_METRICS:
        protocol["metrics"] = list(METRIC_COLUMNS)
    blob = json.dumps(protocol, sort_keys=True)
    return hashlib.sha1(blob.encode()).hexdigest()[:12]
