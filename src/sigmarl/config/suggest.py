""""Did you mean ...?" for a misspelt config key or group option, and Hydra's errors about
them cut to one line (without the schema entries `base_<group>`, which are no options)."""

from __future__ import annotations

import dataclasses
import difflib
import re

from sigmarl.config import Config

_NOT_FOUND = re.compile(r"Could not find '(?P<group>[^']+)/(?P<option>[^'/]+)'")
_NO_KEY = re.compile(r"Could not (?:override|delete) '(?P<key>[^']+)'")
_AMBIGUOUS = re.compile(r"Ambiguous value for argument '(?P<override>[^']+)'")
_LIST_OF_OVERRIDES = re.compile(r"no viable alternative at input '[^']*\[[^']*='")


def schema_keys(node: object = None, prefix: str = "") -> list[str]:
    """Every key of the config schema, dotted (`ppo.epochs`), groups included (`ppo`)."""
    node = Config() if node is None else node
    keys = []
    for f in dataclasses.fields(node):
        value = getattr(node, f.name)
        keys.append(prefix + f.name)
        if dataclasses.is_dataclass(value):
            keys += schema_keys(value, f"{prefix}{f.name}.")
    return keys


def did_you_mean(word: str, choices: list[str]) -> str:
    """' (did you mean X?)' for the closest of `choices`, or ''."""
    close = difflib.get_close_matches(word, choices, n=1, cutoff=0.6)
    return f" (did you mean {close[0]}?)" if close else ""


def unknown_keys_message(unknown: list[str]) -> str:
    keys = schema_keys()
    return "unknown config key(s): " + ", ".join(k + did_you_mean(k, keys) for k in unknown)


def _wrong_form(key: str) -> str:
    """One line for a known key given a mapping it cannot take (Hydra merges a `{...}` value
    into the key's entries and refuses a new one, with the key reported unknown)."""
    if key == "study.variants":
        return ("study.variants={...} cannot replace a study's variants (Hydra merges it into them): "
                "declare them in a study file, study/<name>.yaml in a --config-dir, as "
                "`variants: {LABEL: [override, ...]}`; or add one with +study.variants.K2=['obs.n_nearest=2'], "
                "or pick some with models=[...] (sigmarl sweep)")
    return (f"{key}={{...}} merges into {key}'s entries and cannot add one: set an entry with "
            f"{key}.NAME=VALUE, add one with +{key}.NAME=VALUE, or write it in a config file")


def hydra_error_message(error: BaseException) -> str:
    """Hydra's error about an override, as one line with a suggestion where one is close."""
    message = str(error)
    if found := _NOT_FOUND.search(message):
        group, option = found["group"], found["option"]
        listed = message.split("Available options in", 1)[-1].split("Config search path", 1)[0]
        options = [line.strip() for line in listed.splitlines()[1:]
                   if line.strip() and not line.strip().startswith("base_")]
        suggestion = did_you_mean(option, options).replace("did you mean ", f"did you mean {group}=")
        return (f"{group} has no option {option!r}{suggestion}; "
                f"options: {', '.join(options)}")
    if _AMBIGUOUS.search(message) and (given := _AMBIGUOUS.search(message)["override"]):
        return (f"{given} gives several values, which make several runs: run them with "
                f"`sigmarl sweep {given}` (a list value is written key=[a,b])")
    if missing := _NO_KEY.search(message):
        key = missing["key"]
        if key in schema_keys():  # a known key given a value of the wrong form
            return _wrong_form(key)
        return f"unknown config key {key}{did_you_mean(key, schema_keys())}"
    if _LIST_OF_OVERRIDES.search(message):
        return (f"{message.splitlines()[0]}: an override inside a list is quoted, "
                "e.g. +study.variants.K2=['obs.n_nearest=2']")
    if error.__cause__ is not None and str(error.__cause__).strip():  # e.g. the type that `seed=abc` missed
        message += "\n" + str(error.__cause__).strip().splitlines()[0]
    lines = [line.strip() for line in message.split("Config search path", 1)[0].splitlines()]
    return " ".join(line for line in lines if line and not line.startswith("See https://"))
