"""Checked readers of the files a user or a crash can damage: each answers with the content, or
with one `SigmarlError` line naming the file, what is wrong and the fix (exit code 2), never
a traceback.

- `read_yaml`: any YAML a user writes (a config folder's studies, scenarios, maps); duplicate
  keys are refused (YAML would keep the last one silently).
- `check_config_dir`: every YAML file of a `--config-dir`, before Hydra composes from it.
- `read_run_config`: a run folder's `config.yaml`.
- `read_json`: a JSON record of an expected shape (`seeds_auto.json`, the sweep's plan file,
  `evaluation.json`).
- `rows_measured`: whether a run's evaluation rows are whole and measured under a protocol.

The run folder's other files have their readers beside their writers: `metrics.csv` in
`sigmarl.training.metrics_file.read`, checkpoints (weights and optimiser state) in
`sigmarl.training.checkpoint.load`, evaluation rows in `sigmarl.report.folder.check_rows`.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

import yaml

from sigmarl.errors import SigmarlError

if TYPE_CHECKING:
    from sigmarl.config import Config

# A config folder is small; a file beyond this is not a config someone wrote.
MAX_YAML_BYTES = 4 * 2**20


class _UniqueKeyLoader(yaml.SafeLoader):
    """A safe loader that refuses a key given twice in one mapping."""

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


def rows_measured(rows_file: Path, meta_file: Path, key: str) -> bool:
    """Whether `rows_file` holds whole evaluation rows measured under the protocol `key`: its
    note (`meta_file`) names that key and, for rows saved since it records one, their SHA-256
    (a cut, edited or duplicated line changes it); older rows must pass the report's checks."""
    try:
        meta = json.loads(meta_file.read_text(encoding="utf-8"))
        data = rows_file.read_bytes()
    except (OSError, ValueError):
        return False
    if not isinstance(meta, dict) or meta.get("eval_key") != key:
        return False
    if "rows_sha256" in meta:
        return hashlib.sha256(data).hexdigest() == meta["rows_sha256"]
    import pandas as pd

    from sigmarl.report.folder import check_rows

    try:
        check_rows(pd.read_csv(rows_file, float_precision="round_trip"), rows_file)
    except (SigmarlError, ValueError):  # pandas' parser errors are ValueErrors
        return False
    return True
