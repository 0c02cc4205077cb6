"""Evaluation scenarios: one YAML file each, `conf/scenario/<Name>.yaml` (the file's name is the
scenario's name), holding the map it runs on (`conf/map/<map>.yaml`), its agent count and
whether the paper's Table I has numbers for it. A user adds a scenario with one such file in
their own config folder (`--config-dir`), and `eval.scenarios=[...]` accepts it.

This module reads them without Hydra's global state, so that code running inside a Hydra job
(a sweep's evaluation) can too.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache
from pathlib import Path

from sigmarl.ablation import PAPER_SCENARIOS
from sigmarl.errors import SigmarlError
from sigmarl.paths import config_files


@dataclass(frozen=True)
class Scenario:
    name: str
    map: str  # conf/map/<map>.yaml
    n_agents: int
    paper: bool  # Table I has numbers for it


def scenario_names() -> list[str]:
    """Every scenario on the config search path: Table I's four first, then by name."""
    names = sorted(config_files("scenario"))
    return [s for s in PAPER_SCENARIOS if s in names] + [s for s in names if s not in PAPER_SCENARIOS]


def scenario(name: str) -> Scenario:
    files = config_files("scenario")
    if name not in files:
        import difflib  # lazy: only a misspelt scenario needs it

        close = difflib.get_close_matches(name, scenario_names(), n=1, cutoff=0.6)
        raise SigmarlError(f"unknown scenario {name!r}{f' (did you mean {close[0]}?)' if close else ''}; choose from "
                           f"{', '.join(scenario_names())} "
                           "(or add conf/scenario/<name>.yaml in a --config-dir)")
    return _read(name, files[name])


@cache
def _read(name: str, path: Path) -> Scenario:
    from sigmarl.readers import read_yaml

    values = read_yaml(path, "a scenario file")
    if not isinstance(values, dict) or set(values) - {"map", "n_agents", "paper"} or "map" not in values \
            or "n_agents" not in values:
        raise SigmarlError(f"{path}: a scenario file holds `map`, `n_agents` and optionally `paper`")
    n = values["n_agents"]
    if not isinstance(n, int) or isinstance(n, bool) or n < 1:
        raise SigmarlError(f"{path}: n_agents must be a positive integer, got {n!r}")
    return Scenario(name, str(values["map"]), n, bool(values.get("paper", False)))
