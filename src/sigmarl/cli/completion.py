"""What a shell can complete, and `sigmarl --info`: the config groups with their options and
every key of the schema, read from the config folder and the schema (no extra dependency)."""

from __future__ import annotations

import argparse
import platform
import shlex
from importlib import metadata

import sigmarl
from sigmarl.config.suggest import schema_keys
from sigmarl.paths import conf_dir, user_conf_dirs
from sigmarl.scenarios import scenario_names

GROUPS = ("map", "obs", "network", "ppo", "rules", "study", "hydra/launcher")
BUILTIN_LAUNCHERS = ("basic", "joblib")  # Hydra's own and the joblib plugin's, not in conf/
SWEEP_SHORTHANDS = ("models=", "seeds=")


def group_options(group: str) -> list[str]:
    """The options of a config group (conf/<group>/*.yaml), without the schema entries."""
    names = {p.stem for p in (conf_dir() / group).glob("*.yaml")}
    if group == "hydra/launcher":
        names |= set(BUILTIN_LAUNCHERS)
    return sorted(names)


def override_words(sweep: bool = False) -> list[str]:
    """`group=option` for every group option and `key=` for every settable key."""
    words = [f"{g}={o}" for g in GROUPS for o in group_options(g)]
    keys = schema_keys()
    # the leaves; `model` follows from the obs flags and is never set
    words += [f"{k}=" for k in keys if k != "model" and not any(o.startswith(k + ".") for o in keys)]
    return words + (list(SWEEP_SHORTHANDS) if sweep else [])


def bash_script(parser: argparse.ArgumentParser) -> str:
    """A bash completion function for `sigmarl`: commands, their options, overrides."""
    top = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)][0]
    cases = []
    for name, sub in top.choices.items():
        words = [o for a in sub._actions for o in a.option_strings]
        words += [c for a in sub._actions if a.dest == "action" and a.choices for c in a.choices]
        if any(a.dest == "overrides" for a in sub._actions) and name != "maps":
            words += override_words(sweep=name == "sweep")
        cases.append(f"        {name}) words={shlex.quote(' '.join(words))} ;;")
    commands = " ".join([*top.choices, *(o for a in parser._actions for o in a.option_strings)])
    return "\n".join([
        "# bash completion for sigmarl: eval \"$(sigmarl --completion bash)\" (e.g. in ~/.bashrc)",
        "_sigmarl() {",
        "    local line=${COMP_LINE:0:$COMP_POINT}",
        "    local cur=${line##*[[:space:]]} words",
        "    if [ \"$COMP_CWORD\" -le 1 ]; then",
        f"        words={shlex.quote(commands)}",
        "    else",
        "        case ${COMP_WORDS[1]} in",
        *cases,
        "        *) words='' ;;",
        "        esac",
        "    fi",
        "    # bash splits words at = and : (COMP_WORDBREAKS): complete only the part after them",
        "    local prefix=${cur%\"${cur##*[=:]}\"}",
        "    COMPREPLY=($(compgen -W \"$words\" -- \"$cur\"))",
        "    COMPREPLY=(\"${COMPREPLY[@]#\"$prefix\"}\")",
        "    [[ ${#COMPREPLY[@]} -eq 1 && $COMPREPLY == *= ]] && compopt -o nospace",
        "    return 0",
        "}",
        "complete -F _sigmarl sigmarl",
        "",
    ])


def info() -> str:
    """`sigmarl --info`: versions, where the configs are, the groups and their options; the
    options of the user's config folders (--config-dir, $SIGMARL_CONFIG_PATH) beside the
    package's, each marked with its folder's number."""
    def version(package: str) -> str:
        try:
            return metadata.version(package)
        except metadata.PackageNotFoundError:
            return "not installed"

    users = user_conf_dirs()
    lines = [f"sigmarl {sigmarl.__version__} (Python {platform.python_version()}, {sigmarl.__path__[0]})",
             f"config folder: {conf_dir()}"]
    lines += [f"your config folder [{i}]: {folder} (searched first; a name it shares shadows sigmarl's, marked *)"
              for i, folder in enumerate(users, 1)]
    lines += ["config groups (GROUP=OPTION; defaults: map=cpm_intersection obs=full network=paper ppo=paper "
              "rules=ours study=paper hydra/launcher=joblib in a sweep):"]
    lines += [f"  {g:<15} {', '.join(group_options(g))}{_users_options(g, users)}" for g in GROUPS]
    shipped = [s for s in scenario_names() if (conf_dir() / "scenario" / f"{s}.yaml").is_file()]
    lines += [f"scenarios (eval.scenarios=[...]): {', '.join(shipped)}{_users_options('scenario', users)}",
              "packages: " + ", ".join(f"{p} {version(p)}" for p in
                                       ("torch", "torchrl", "tensordict", "vmas", "hydra-core", "mlflow")),
              "print a command's composed config: sigmarl COMMAND --cfg job [overrides]"]
    return "\n".join(lines)


def _users_options(group: str, users: list) -> str:
    """`; [1] a, b*` for the options each user folder adds to `group` (* where one shadows
    the package's), or ""."""
    shipped = {p.stem for p in (conf_dir() / group).glob("*.yaml")}
    parts = []
    for i, folder in enumerate(users, 1):
        if names := sorted(p.stem for p in (folder / group).glob("*.yaml")):
            parts.append(f"[{i}] " + ", ".join(n + "*" * (n in shipped) for n in names))
    return "".join(f"; {p}" for p in parts)
