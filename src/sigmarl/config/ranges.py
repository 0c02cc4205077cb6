"""What values a config key takes, declared once on its field (`ranged(...)` is a dataclass
`field` whose metadata holds a `Range`): `sigmarl.compose.validate` checks every key against it, and the
schema-driven fuzz test (tests/test_config_fuzz.py) tries the values just outside it, so that a
new key with a range is checked and fuzzed without being named anywhere else.

A size (`size=True`) is a count that sizes tensors, threads or work: its upper end is a
generous cap, far above any real use, so that an absurd value (10**12 frames, a million
threads) is one line at composition instead of a machine out of memory or of process ids.
"""

from __future__ import annotations

import dataclasses
import math
import re
from dataclasses import dataclass
from typing import Any

INF = math.inf
# numpy's legacy generator (np.random.seed) takes seeds in 0..2**32-1, torch any up to 2**64-1
SEED_MAX = 2**32 - 1


@dataclass(frozen=True)
class Range:
    lo: float = -INF
    hi: float = INF
    lo_open: bool = False  # (lo, ...: lo itself is outside
    hi_open: bool = False
    size: bool = False  # sizes memory, threads or work: fuzzed with absurd values too
    unit: str = ""  # shown after the interval: "in (0, 90) degrees"
    choices: tuple[str, ...] = ()  # a string key's allowed values
    pattern: str = ""  # a string key's allowed form, matched whole
    form: str = ""  # the pattern in words, for the error line

    def holds(self, value: Any) -> bool:
        if self.choices:
            return value in self.choices
        if self.pattern:
            return isinstance(value, str) and re.fullmatch(self.pattern, value) is not None
        above = value > self.lo if self.lo_open else value >= self.lo
        below = value < self.hi if self.hi_open else value <= self.hi
        return above and below

    def text(self) -> str:
        """What `holds` allows, as the error line says it: positive, >= 0, in [0, 1], 1..1024."""
        if self.choices:
            return "one of " + ", ".join(self.choices)
        if self.pattern:
            return self.form or f"of the form {self.pattern}"
        unit = f" {self.unit}" if self.unit else ""
        if self.hi == INF:
            if self.lo == 0:
                return ("positive" if self.lo_open else ">= 0") + (f" ({self.unit})" if unit else "")
            return f"{'>' if self.lo_open else '>='} {_num(self.lo)}{unit}"
        if isinstance(self.lo, int) and isinstance(self.hi, int) and not (self.lo_open or self.hi_open):
            return f"in {self.lo}..{self.hi}{unit}"
        return f"in {'(' if self.lo_open else '['}{_num(self.lo)}, {_num(self.hi)}{')' if self.hi_open else ']'}{unit}"


def _num(x: float) -> str:
    return str(int(x)) if float(x).is_integer() and abs(x) < 2**53 else repr(x)


def ranged(default: Any = dataclasses.MISSING, *, factory: Any = dataclasses.MISSING, **limits: Any) -> Any:
    """A dataclass field of this default (or `factory`) whose values must lie in `Range(**limits)`
    (a list's or a dict's: each element)."""
    if isinstance(default, float):  # a float key's ends print as floats: in [0.0, 1.0] reads as real
        limits = {k: float(v) if k in ("lo", "hi") else v for k, v in limits.items()}
    metadata = {"range": Range(**limits)}
    if factory is not dataclasses.MISSING:
        return dataclasses.field(default_factory=factory, metadata=metadata)
    return dataclasses.field(default=default, metadata=metadata)


def range_of(f: dataclasses.Field) -> Range | None:
    return f.metadata.get("range")


def out_of_range(key: str, value: Any, rng: Range) -> str | None:
    """None if `value` (each element of a list or a dict) lies in `rng`; else the error line."""
    items = value.values() if isinstance(value, dict) else value if isinstance(value, list | tuple) else [value]
    for item in items:
        if isinstance(item, bool) or (not rng.choices and not rng.pattern and not isinstance(item, int | float)):
            continue  # a type is OmegaConf's to check
        if not rng.holds(item) and (rng.choices or rng.pattern):
            return f"{key}={item!r} is not {rng.text()}"
        if not rng.holds(item):
            shown = repr(item) if isinstance(item, str) else _short(item)
            return f"{key} must be {rng.text()}, got {shown}"
    return None


def _short(x: float) -> str:
    """`x`, or its size where printing it would flood the line."""
    if isinstance(x, int) and x.bit_length() >= 128:
        return f"a number of {x.bit_length()} bits"
    return str(x)


def check_ranges(node: Any, prefix: str = "") -> None:
    """Every key of a config record (and of the records in it) in its declared range; otherwise
    one SigmarlError naming the key."""
    from sigmarl.errors import SigmarlError

    for f in dataclasses.fields(node):
        value, key = getattr(node, f.name), f"{prefix}{f.name}"
        if dataclasses.is_dataclass(value):
            check_ranges(value, key + ".")
        elif (rng := range_of(f)) is not None and (wrong := out_of_range(key, value, rng)):
            raise SigmarlError(wrong)
