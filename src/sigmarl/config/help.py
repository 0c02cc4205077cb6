"""One line of help per config key, read from the config dataclasses' source.

The help of a field is the string literal on the line after it, as in CleanRL's `Args`; a
group's help is the first line of its class docstring. Python drops those literals at run
time, so they are read from the source with `ast`: the one source of `sigmarl --info KEY`,
`sigmarl train --help`'s key list and the generated configuration reference.
"""

from __future__ import annotations

import ast
import dataclasses
import inspect
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Any, get_type_hints

from sigmarl.errors import SigmarlError


@dataclass(frozen=True)
class KeyHelp:
    key: str  # dotted: ppo.lr
    type: str  # as annotated: list[int]
    default: Any  # MISSING keys: "???"
    help: str  # "" where the source has none (a test fails then)
    group: bool = False  # a config group (a dataclass), not a settable value


@cache
def _field_docs(cls: type) -> dict[str, tuple[str, str]]:
    """field -> (annotation as written, help line) for one dataclass, from its module's source."""
    tree = ast.parse(Path(inspect.getsourcefile(cls)).read_text(encoding="utf-8"))
    node = next((n for n in ast.walk(tree) if isinstance(n, ast.ClassDef) and n.name == cls.__name__), None)
    docs: dict[str, tuple[str, str]] = {}
    if node is None:  # a generated class (`sigmarl.config.map.MapConfig`): its FIELD_SOURCES say
        return docs
    for stmt, after in zip(node.body, [*node.body[1:], None], strict=True):
        if isinstance(stmt, ast.AnnAssign) and isinstance(stmt.target, ast.Name):
            text = ""
            if (isinstance(after, ast.Expr) and isinstance(after.value, ast.Constant)
                    and isinstance(after.value.value, str)):
                text = " ".join(after.value.value.split())
            docs[stmt.target.id] = (ast.unparse(stmt.annotation), text)
    return docs


def _default(f: dataclasses.Field) -> Any:
    if f.default is not dataclasses.MISSING:
        return f.default
    if f.default_factory is not dataclasses.MISSING:
        return f.default_factory()
    return "???"


def _summary(cls: type) -> str:
    return (inspect.getdoc(cls) or "").split("\n\n")[0].replace("\n", " ")


@cache
def key_help(schema: type | None = None) -> tuple[KeyHelp, ...]:
    """Every key of the schema (default: `sigmarl.config.Config`), groups first-class, in order."""
    if schema is None:
        # lazy: the parser's key list is built without omegaconf (start-up)
        from sigmarl.config import Config

        schema = Config
    return tuple(_walk(schema, ""))


def _walk(cls: type, prefix: str):
    docs, types = _field_docs(cls), get_type_hints(cls)
    sources = getattr(cls, "FIELD_SOURCES", {})  # a generated class's keys, by the class declaring each
    for f in dataclasses.fields(cls):
        key = f"{prefix}{f.name}"
        # a generated field (ObsConfig's strategy flags) carries its help in its class's FIELD_HELP
        declared = (getattr(types[f.name], "__name__", str(types[f.name])), getattr(cls, "FIELD_HELP", {}).get(f.name, ""))
        annotation, text = (_field_docs(sources[f.name]) if f.name in sources else docs).get(f.name, declared)
        if dataclasses.is_dataclass(types[f.name]):
            yield KeyHelp(key, annotation, None, text or _summary(types[f.name]), group=True)
            yield from _walk(types[f.name], key + ".")
        else:
            yield KeyHelp(key, annotation, _default(f), text)


def describe(query: str) -> str:
    """`sigmarl --info KEY`: the key's type, default and help; a group's keys, one a line."""
    keys = key_help()
    hits = [k for k in keys if k.key == query or k.key.startswith(query + ".")]
    if not hits:
        # lazy: the parser's key list is built without omegaconf (start-up)
        from sigmarl.config.suggest import did_you_mean

        raise SigmarlError(f"no config key {query!r}{did_you_mean(query, [k.key for k in keys])}; "
                           "sigmarl --info lists the groups")
    return "\n".join(_line(k) for k in hits)


def shown(value: Any) -> str:
    """A default as a person would type it: a float at 12 significant digits (0.035, never a
    computed default's binary tail 0.034999999999999996), anything else as its repr."""
    if isinstance(value, float):
        return format(value, ".12g") if "e" not in format(value, ".12g") else repr(value)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(shown(v) for v in value) + "]"
    return repr(value)


def _line(k: KeyHelp) -> str:
    if k.group:
        return f"{k.key}: {k.help}"
    return f"{k.key} ({k.type}, default {shown(k.default)}): {k.help}"


def keys_epilog(prefix: str = "") -> str:
    """The keys and their help, for `sigmarl train --help` (those under `prefix`, with their
    defaults, for `sigmarl evaluate --help`)."""
    what = f"{prefix.rstrip('.')} keys and their defaults" if prefix else "config keys"
    lines = [f"{what} (override as KEY=VALUE; `sigmarl --info KEY` for one key or group):"]
    lines += [f"  {k.key}: {k.help}" if k.group else f"    {k.key}={shown(k.default)}  {k.help}"
              for k in key_help() if k.key.startswith(prefix)]
    return "\n".join(lines)
