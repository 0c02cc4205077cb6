"""Whether a folder is sigmarl's to write: empty, or holding what sigmarl writes in a run folder,
told by content as well as by name (a user's own `config.yaml` is not a run's config). Anything
else is refused in one line before a single file in it changes: `run_dir=mywork` never
overwrites a user's notes, `run_dir=/` never writes into the root.

`RUN_FILES` (every file `sigmarl.run` names, `provenance.json` included) and `RUN_FILE_PATTERNS`
declare every file sigmarl may write in a run folder. A feature that writes another file there
(an imported policy's rows, a metric's own file, an animation) names it in `sigmarl.run` or adds
a pattern here, or its folders are refused as not sigmarl's."""

from __future__ import annotations

import re
from pathlib import Path

from sigmarl import run
from sigmarl.errors import SigmarlError

# every file `sigmarl.run` names (its *_FILE and *_META constants): a file added there is declared here
RUN_FILES = frozenset(value for name, value in vars(run).items()
                      if name.endswith(("_FILE", "_META")) and isinstance(value, str))
RUN_CONFIG_KEYS = frozenset({"model", "seed", "ppo", "env", "eval"})  # in every run's config.yaml, old ones too
RUN_FILE_PATTERNS = (
    re.compile(r"evaluation_rows-[0-9a-f]{12}\.(csv|json)"),  # an evaluation under another protocol
    re.compile(r"\.(.+)\.[^.]+\.tmp"),  # run.write_atomic's temporary file, left by a kill (group 1: its target)
)


class NotOurs(SigmarlError):
    """A folder that is not sigmarl's: nothing may be written in it, not even a failure's mark."""


def check_ours(folder: Path) -> None:
    """Refuse, in one line naming what is not sigmarl's, a `folder` that holds anything but a
    run folder's files; an absent or empty folder passes."""
    folder = Path(folder)
    if not folder.exists() and not folder.is_symlink():
        return
    if not folder.is_dir():
        raise NotOurs(f"run_dir {folder} is a file, not a folder; choose another run_dir=...")
    stranger = _stranger(folder)
    if stranger:
        raise NotOurs(f"run_dir {folder} is not a sigmarl run folder ({stranger}); sigmarl writes only into "
                           "an empty folder or one it wrote, and leaves this one as it is: choose another run_dir=...")


def _stranger(folder: Path) -> str | None:
    """What in `folder` sigmarl did not write, in words; None if all of it is a run's."""
    try:
        entries = sorted(folder.iterdir())
    except OSError as e:
        return f"it cannot be listed: {e.strerror}"
    for entry in entries:
        name = entry.name
        temporary = RUN_FILE_PATTERNS[1].fullmatch(name)
        if temporary and temporary.group(1) in RUN_FILES:
            continue
        if entry.is_symlink() or not entry.is_file():
            return f"it holds {name}, which is no file sigmarl writes"
        if name not in RUN_FILES and not RUN_FILE_PATTERNS[0].fullmatch(name):
            return f"it holds {name}, which sigmarl does not write"
        if (wrong := _not_ours(entry, folder)) is not None:
            return f"its {name} {wrong}"
    return None


def _not_ours(path: Path, folder: Path) -> str | None:
    """Why a file of a run folder's name holds what sigmarl never wrote there, or None. Only
    what a user would keep under these names is read (a damaged record of ours is its reader's
    to refuse or repair)."""
    name = path.name
    if name == run.CONFIG_FILE:
        if run.Run(folder).resume_file.is_file():
            return None  # a resume rewrites a damaged config.yaml from its checkpoint
        from sigmarl.readers import read_run_config, read_yaml

        try:
            values = read_yaml(path, "a run's config", "")
            read_run_config(path)
        except SigmarlError:
            return "is not a run's training config"
        # a run config's reader fills in what an older one lacks: a user's YAML would pass it
        if not isinstance(values, dict) or not RUN_CONFIG_KEYS <= values.keys():
            return "is not a run's training config"
        return None
    head = _head(path)
    if name == run.METRICS_FILE and head and not head.startswith(b"iteration"):
        return "is not a training's metrics (its first column is not iteration)"
    if name == run.RUN_ID_FILE and (len(head) > 200 or b"\n" in head.strip() or b"\0" in head):
        return "is not a run id"
    return None


def _head(path: Path) -> bytes:
    try:
        with path.open("rb") as f:
            return f.read(256)
    except OSError:
        return b""
