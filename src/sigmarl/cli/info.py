"""What the command line prints instead of running: `--cfg` (the composed config), `--info`
(versions, config folders and groups, or one key's help), `--completion bash`, and the config
keys at the end of `train --help` and `evaluate --help`."""

from __future__ import annotations

import argparse
import os
import sys

from sigmarl.errors import SigmarlError
from sigmarl.paths import add_user_conf_dir


def print_cfg(args: argparse.Namespace) -> int:
    """`--cfg job|hydra|all`, as in Hydra apps: the config the command would run with (composed
    and resolved; a sweep prints each job's), Hydra's own settings, or both."""
    # lazy: `sigmarl --help` and a bad argument answer without Hydra, torch or MLflow
    from omegaconf import OmegaConf

    from sigmarl.compose import compose_config, hydra_config
    from sigmarl.config import to_yaml

    overrides = list(args.overrides)
    jobs: list[list[str]] = [[]]
    if args.command == "sweep":
        from sigmarl.sweep import job_overrides

        overrides, jobs = job_overrides(overrides)
    if args.cfg in ("hydra", "all"):
        print(OmegaConf.to_yaml({"hydra": hydra_config(overrides)}), end="")
    if args.cfg in ("job", "all"):
        for job in jobs:
            if job:
                print(f"# job: {' '.join(job)}")
            print(to_yaml(compose_config([*(o for o in overrides if not o.startswith("hydra")), *job])), end="")
    return 0


class PrintAndExit(argparse.Action):
    """An option that prints something and ends the command, like --version."""

    def __init__(self, option_strings, dest, text, **kwargs):
        self.text = text
        super().__init__(option_strings, dest, **kwargs)

    def __call__(self, parser, namespace, values, option_string=None):
        try:
            print(self.text(parser, values, namespace))
        except BrokenPipeError:  # `sigmarl --info | head`: the reader left
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        parser.exit()


def completion_script(parser: argparse.ArgumentParser, shell: str, namespace: argparse.Namespace) -> str:
    # lazy: `sigmarl --help` and a bad argument answer without Hydra, torch or MLflow
    from sigmarl.cli.completion import bash_script

    return bash_script(parser)


def info_text(parser: argparse.ArgumentParser, key: str | None, namespace: argparse.Namespace) -> str:
    try:
        for folder in namespace.config_dir:  # those named before --info: theirs are listed too
            add_user_conf_dir(folder)
    except SigmarlError as e:
        parser.exit(2, f"sigmarl: error: {e}\n")
    if key:
        # lazy: config_help's dataclass introspection costs `sigmarl --help` a third of its start-up
        from sigmarl.config.help import describe

        try:
            return describe(key)
        except SigmarlError as e:
            parser.exit(2, f"sigmarl: error: {e}\n")
    # lazy: `sigmarl --help` and a bad argument answer without Hydra, torch or MLflow
    from sigmarl.cli.completion import info

    return info()


KEYS_EPILOG = "config keys"  # the epilog that KeysHelp replaces with the keys
EVAL_KEYS_EPILOG = "eval keys"  # ... with the evaluation's keys and their defaults


class KeysHelp(argparse.RawDescriptionHelpFormatter):
    """`sigmarl train --help` ends with every config key and its help line (the config's
    source is read only when the help is printed)."""

    def add_text(self, text: str | None) -> None:
        if text in (KEYS_EPILOG, EVAL_KEYS_EPILOG):
            # lazy: config_help's dataclass introspection costs `sigmarl --help` a third of its start-up
            from sigmarl.config.help import keys_epilog

            text = keys_epilog("eval." if text == EVAL_KEYS_EPILOG else "")
        super().add_text(text)
