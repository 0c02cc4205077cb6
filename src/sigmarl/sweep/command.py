"""What `sigmarl sweep` was told: its overrides read by Hydra's own parser (lists, quoted
strings, range(), choice()) and sorted by what the sweep does with each."""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass, field

from hydra.core.override_parser.overrides_parser import OverridesParser
from hydra.core.override_parser.types import Override
from hydra.errors import HydraException

from sigmarl.errors import SigmarlError

SET_BY_THE_SWEEP = ("model", "overrides", "fingerprint")


@dataclass
class Command:
    fixed: list[str] = field(default_factory=list)  # overrides that every job shares
    hydra: list[str] = field(default_factory=list)  # Hydra's own settings (launcher, ...)
    sweeps: list[tuple[str, list[str]]] = field(default_factory=list)  # key, values: a variant per value
    models: list[str] | None = None  # models=[...]: the study's variants picked by label
    seeds: list[str] | None = None  # seeds=[...] or seed=a,b
    obs: list[str] | None = None  # obs=a,b: presets that replace the study's variants


def read_command(user: Sequence[str]) -> Command:
    """The sweep's overrides sorted; a shorthand given twice or selecting nothing is refused."""
    command, seed = Command(), None
    for o in _parse(user):
        key = o.key_or_group
        if key == "models":
            command.models = _items(o)
        elif key == "seeds":
            command.seeds = _items(o)
        elif _is_hydra(o):
            command.hydra.append(o.input_line)
        elif key == "seed":
            seed = _values(o)
        elif key == "obs":
            command.obs = _values(o)
        elif key in SET_BY_THE_SWEEP or key.startswith("study.job"):
            raise SigmarlError(f"{key} is set by the sweep itself (choose variants with models=[...])")
        elif o.is_sweep_override():
            command.sweeps.append((o.get_key_element(), _values(o)))
        else:
            command.fixed.append(o.input_line)
    if command.seeds is not None and seed is not None:
        raise SigmarlError("give either seeds=[...] or seed=..., not both")
    command.seeds = command.seeds if command.seeds is not None else seed
    if command.models is not None and command.obs is not None:
        raise SigmarlError("give either models=[...] or obs=..., not both")
    for short, given in (("models", command.models), ("seeds", command.seeds)):
        if given is not None and not given:
            raise SigmarlError(f"{short}=[] selects no jobs")
    return command


def override_key(override: str) -> str:
    """The key or group an override string sets (`+a.b=1` -> a.b, `obs=full` -> obs)."""
    return override.split("=", 1)[0].lstrip("+~")


def slug(key: str, value: str) -> str:
    """`network.hidden`, `[64,64]` -> hidden-64-64: a label part that names a folder."""
    leaf = re.split(r"[./]", key)[-1]
    return f"{leaf}-" + (re.sub(r"[^A-Za-z0-9.]+", "-", value).strip("-") or "x")


def _parse(items: Sequence[str]) -> list[Override]:
    try:
        return OverridesParser.create().parse_overrides(list(items))
    except HydraException as e:
        raise SigmarlError(f"bad override: {e}") from e
    except ValueError as e:  # e.g. an integer too long for Python to parse (over 4300 digits)
        raise SigmarlError(f"bad override: {str(e).splitlines()[0]}") from e


def _values(o: Override) -> list[str]:
    """What one override takes, as Hydra override strings: its single value, or each value
    of a sweep (`a,b`, `range(3)`, `choice(...)`)."""
    if not o.is_sweep_override():
        return [o.get_value_element_as_str()]
    if not o.is_discrete_sweep():
        raise SigmarlError(f"{o.input_line}: a sweep needs discrete values (a,b or range() or choice()), "
                           "not an interval")
    return list(o.sweep_string_iterator())


def _items(o: Override) -> list[str]:
    """A shorthand's values: the elements of `[a,b]`, the values of a sweep, or one value."""
    if not o.is_sweep_override() and isinstance(o.value(), list):
        return [str(v) for v in o.value()]
    return _values(o)


def _is_hydra(o: Override) -> bool:
    return o.key_or_group.split("/")[0].split(".")[0] == "hydra"
