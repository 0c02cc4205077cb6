"""Checked readers of the files a user or a crash can damage: each answers with the content, or
with one `SigmarlError` line naming the file, what is wrong and the fix (exit code 2), never
a traceback.

- `read_yaml`: any YAML a user writes (a config folder's studies, scenarios, maps); duplicate
  keys are refused (YAML would keep the last one silently), and so are aliases (a "billion
  laughs" expands beyond memory).
- `check_config_dir`: every YAML file of a `--config-dir`, before Hydra composes from it.
- `read_run_config`: a run folder's `config.yaml`.
- `read_json`: a JSON record of an expected shape (`seeds_auto.json`, the sweep's plan file,
  `evaluation.json`).
- `read_metrics`: a run's `metrics.csv`, line by line (whole-number iterations in
  1..MAX_ITERATION, finite values); `read_training_curve`: the same file as a report reads it.
  A resume reads it through `sigmarl.training.metrics_file.read` (every iteration once, in order).

The run folder's other files have their readers beside their writers: checkpoints (weights,
optimiser state, checksum) in `sigmarl.training.checkpoint.load`, evaluation rows in
`sigmarl.rows` (`check_rows`, `rows_measured`).
"""

from __future__ import annotations

import json
import math
from itertools import islice
from pathlib import Path
from typing import TYPE_CHECKING, Any

import yaml

from sigmarl.errors import SigmarlError

if TYPE_CHECKING:
    from sigmarl.config import Config

# A config folder is small; a file beyond this is not a config someone wrote.
MAX_YAML_BYTES = 4 * 2**20
# Far beyond any real training (the paper's has 250 iterations), but a bound: a garbled
# iteration (1e308, 99999999999) is refused instead of reported.
MAX_ITERATION = 10**7
METRICS_FIX = "restore it from a copy, or move the run folder away and train again"


class _UniqueKeyLoader(yaml.SafeLoader):
    """A safe loader that refuses a key given twice in one mapping, and any alias (`*name`):
    a kilobyte of nested aliases (a "billion laughs") expands to more nodes than memory holds
    once OmegaConf copies each reference, and no config of sigmarl's needs one."""

    def compose_node(self, parent: Any, index: Any) -> Any:
        if self.check_event(yaml.AliasEvent):
            event = self.peek_event()
            raise yaml.composer.ComposerError(None, None, f"an alias (*{event.anchor}) is not allowed; write the "
                                              "value out", event.start_mark)
        return super().compose_node(parent, index)

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict:
        seen: set = set()
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=deep)
            if isinstance(key, list | dict):
                raise yaml.constructor.ConstructorError(None, None, "a mapping key must be a plain value",
                                                        key_node.start_mark)
            if key in seen:
                raise yaml.constructor.ConstructorError(None, None, f"duplicate key {key!r}", key_node.start_mark)
            seen.add(key)
        return super().construct_mapping(node, deep=deep)


def _text(path: Path, what: str, fix: str) -> str:
    try:
        if path.stat().st_size > MAX_YAML_BYTES:
            raise SigmarlError(f"{path}: {what} of over {MAX_YAML_BYTES >> 20} MiB; {fix}")
        return path.read_bytes().decode("utf-8")
    except UnicodeDecodeError as e:
        raise SigmarlError(f"{path}: {what} is not UTF-8 text (byte {e.start}); {fix}") from None
    except OSError as e:
        raise SigmarlError(f"{path}: cannot read {what} ({e.strerror}); {fix}") from None


def read_yaml(path: str | Path, what: str = "a YAML file", fix: str = "correct the file") -> Any:
    """The YAML document at `path`, or one line naming the file, line and problem."""
    path = Path(path)
    text = _text(path, what, fix)
    try:
        return yaml.load(text, Loader=_UniqueKeyLoader)  # noqa: S506 (a SafeLoader)
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None) or getattr(e, "context_mark", None)
        where = f", line {mark.line + 1}" if mark is not None else ""
        problem = getattr(e, "problem", None) or str(e).splitlines()[0]
        raise SigmarlError(f"{path}{where}: {problem} (not valid YAML); {fix}") from None
    except (ValueError, TypeError, RecursionError) as e:  # e.g. a date out of range, nesting too deep
        raise SigmarlError(f"{path}: {type(e).__name__} reading {what}; {fix}") from None


def check_config_dir(folder: Path) -> None:
    """Read every YAML file of a user's config folder (studies, scenarios, maps, ...), so that a
    syntax error or a duplicate key is one line before Hydra composes from it."""
    for path in sorted(folder.rglob("*.yaml")):
        values = read_yaml(path, "a config file", "correct it, or move it out of the --config-dir")
        if values is not None and not isinstance(values, dict):
            raise SigmarlError(f"{path}: a config file holds keys and values, not a {type(values).__name__}; "
                               "correct it, or move it out of the --config-dir")


def read_run_config(path: Path) -> Config:
    """A run folder's config.yaml as a `Config` (its fingerprint not yet recomputed)."""
    from sigmarl.config import config_from_dict

    fix = "move the run folder away (or restore the file) and run again"
    values = read_yaml(path, "a run's config", fix)
    if not isinstance(values, dict):
        raise SigmarlError(f"{path}: a run's config holds keys and values, not a {type(values).__name__}; {fix}")
    try:
        return config_from_dict(values, what=str(path))
    except SigmarlError as e:
        raise SigmarlError(f"{str(e).splitlines()[0]}; {fix}") from None


def read_json(path: Path, what: str, fix: str, shape: dict[str, type] | None = None) -> Any:
    """A JSON object of `path`, with each key of `shape` present and of its type; else one line."""
    try:
        value = json.loads(_text(path, what, fix))
    except ValueError as e:  # also a JSONDecodeError
        raise SigmarlError(f"{path}: {what} is not valid JSON ({str(e).splitlines()[0]}); {fix}") from None
    if shape is None:
        return value
    if not isinstance(value, dict):
        raise SigmarlError(f"{path}: {what} must be a JSON object, not a {type(value).__name__}; {fix}")
    for key, kind in shape.items():
        if not isinstance(value.get(key), kind) or (kind is int and isinstance(value[key], bool)):
            found = "missing" if key not in value else f"a {type(value[key]).__name__}"
            raise SigmarlError(f"{path}: {what}'s {key!r} must be a {kind.__name__}, it is {found}; {fix}")
    return value


def read_metrics(path: Path, upto: int | None = None, whole: bool = False,
                 fix: str = METRICS_FIX) -> list[tuple[int, dict[str, float]]]:
    """The rows of a run's `metrics.csv` in file order, [(iteration, {name: value})], rows after
    `upto` left out; each checked: as many fields as the header, the iteration a whole number in
    1..MAX_ITERATION, every value a finite number. Unless `whole`, a bad last line is taken for
    the one a kill cut short while it was appended, and dropped. Anything else is one
    SigmarlError naming the file and line."""
    if upto == 0:  # a resume before the first iteration needs no row (a cut header included)
        return []
    if not path.exists():
        if upto:
            raise SigmarlError(f"{path} is missing, and its run has done {upto} iteration(s); {fix}")
        return []
    try:
        lines = path.read_bytes().decode("utf-8").split("\n")
    except UnicodeDecodeError as e:
        raise SigmarlError(f"{path} is not a metrics file (byte {e.start} is not text); {fix}") from None
    except OSError as e:
        raise SigmarlError(f"{path}: cannot read it ({e.strerror}); {fix}") from None
    if lines and lines[-1] == "":
        lines.pop()  # the file ends with a newline
    if not lines:
        if upto:
            raise SigmarlError(f"{path} is empty, and its run has done {upto} iteration(s); {fix}")
        return []
    names = lines[0].split(",")[1:]
    if lines[0].split(",")[0] != "iteration" or not names or len(set(names)) < len(names):
        raise SigmarlError(f"{path}: line 1 is not a header `iteration,<metric>,...`; {fix}")
    rows = []
    for n, line in enumerate(lines[1:], 2):
        try:
            it, values = _metrics_row(line, names)
        except ValueError as e:
            if n == len(lines) and not whole:  # the line a kill cut short while it was appended
                break
            raise SigmarlError(f"{path}: line {n}: {e}; {fix}") from None
        if upto is None or it <= upto:
            rows.append((it, dict(zip(names, values, strict=True))))
    return rows


def _metrics_row(line: str, names: list[str]) -> tuple[int, list[float]]:
    """A line's iteration and values; a ValueError says what is wrong with it."""
    fields = line.split(",")
    if len(fields) != len(names) + 1:
        raise ValueError(f"{len(fields)} field(s), not the header's {len(names) + 1}")
    it = fields[0].strip()
    # digits only (int() would take "1_0" or "+3"), and few enough that int() cannot refuse them
    if not (it.isascii() and it.isdigit() and len(it) <= len(str(MAX_ITERATION))
            and 0 < int(it) <= MAX_ITERATION):
        raise ValueError(f"iteration {fields[0][:20]!r} is not a whole number in 1..{MAX_ITERATION}")
    values = []
    for name, field in zip(names, fields[1:], strict=True):
        try:
            value = float(field)
        except ValueError:
            raise ValueError(f"{name} {field[:20]!r} is not a number") from None
        if not math.isfinite(value):  # a report would average it into its tables
            raise ValueError(f"{name} is {field.strip()[:20]}, not a finite number")
        values.append(value)
    return int(it), values


def read_training_curve(path: Path) -> list[tuple[int, dict[str, float]]]:
    """A finished run's `metrics.csv` as a report reads it: every line whole and checked
    (`read_metrics`) and iterations 1..n each present, in iteration order; an iteration given
    twice (a resume before resumes cut the file) counts with its last row."""
    fix = "restore it from a copy, or delete it to report the run without its training curve"
    last = dict(read_metrics(path, whole=True, fix=fix))  # a later row replaces an earlier one
    n = max(last, default=0)
    if len(last) != n or not n:  # the keys lie in 1..n: n of them are each of 1..n
        lost = list(islice((it for it in range(1, n + 1) if it not in last), 6))
        what = "holds no iterations" if not n else \
            f"lacks iteration(s) {', '.join(map(str, lost[:5]))}{' ...' if len(lost) > 5 else ''} of 1..{n}"
        raise SigmarlError(f"{path} {what}; {fix}")
    return [(it, last[it]) for it in range(1, n + 1)]
