"""Where the Hydra config tree lives, and the users' own config folders searched before it.

The tree is kept at the top of the repository (`conf/`) and reached from the package through
the symlink `src/sigmarl/conf -> ../../conf`: the same path serves a checkout on PYTHONPATH, an
editable install and a wheel (building follows the link and ships real files as
`sigmarl/conf/`).

A user's own studies, scenarios and maps live in their own folders (`--config-dir DIR` on the
command line, or $SIGMARL_CONFIG_PATH, folders separated by ':'), laid out like conf/
(`study/widths.yaml`, `scenario/My-Map.yaml`, `map/my_map.yaml`). They are searched first, so
a user's file of the same name shadows the package's. The variable also carries them into a
sweep's job processes.
"""

from __future__ import annotations

import os
from pathlib import Path

from sigmarl.errors import SigmarlError

CONFIG_PATH = "SIGMARL_CONFIG_PATH"


def conf_dir() -> Path:
    """The package's conf/ (see above), or $SIGMARL_CONF."""
    if env := os.environ.get("SIGMARL_CONF"):
        return Path(env).resolve()
    return (Path(__file__).resolve().parent / "conf").resolve()


def user_conf_dirs() -> list[Path]:
    """The users' config folders, in search order."""
    return [Path(p).resolve() for p in os.environ.get(CONFIG_PATH, "").split(os.pathsep) if p]


def add_user_conf_dir(folder: str | Path) -> None:
    """Search `folder` before the package's conf/ (here and in every process started from here)."""
    path = Path(folder).expanduser().resolve()
    if not path.is_dir():
        raise SigmarlError(f"--config-dir {folder}: no such folder")
    from sigmarl.readers import check_config_dir

    check_config_dir(path)  # a broken file is one line here, not a traceback from Hydra
    dirs = [str(p) for p in user_conf_dirs() if p != path]
    os.environ[CONFIG_PATH] = os.pathsep.join([*dirs, str(path)])


def conf_dirs() -> list[Path]:
    """Every config folder, in search order: the users' first, the package's last."""
    return [*user_conf_dirs(), conf_dir()]


def config_files(group: str) -> dict[str, Path]:
    """name -> file of every `<group>/<name>.yaml` on the search path (the first one wins)."""
    found: dict[str, Path] = {}
    for folder in conf_dirs():
        for path in sorted((folder / group).glob("*.yaml")):
            found.setdefault(path.stem, path)
    return found


def ensure_writable(folder: Path, what: str) -> None:
    """Create `folder` and check that a file can be written there, before any work; otherwise
    a SigmarlError naming it and `what` to do ("choose another run_dir=...")."""
    import tempfile  # lazy: the CLI imports paths at start-up; tempfile costs it 4 ms

    try:
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError as e:
        raise SigmarlError(f"{folder} is not writable ({e.strerror}); {what}") from e


def check_surroundings() -> None:
    """The working folder and $SIGMARL_CACHE are usable, or one line says which is not, before
    a command starts: Hydra asks for the working folder (gone if it was deleted under the
    shell), and the store's template cache is a folder (`sigmarl.tracking.store`)."""
    try:
        os.getcwd()
    except OSError as e:
        raise SigmarlError(f"the working folder cannot be read ({e.strerror}): was it deleted? cd to an "
                           "existing folder and run again") from None
    cache = os.environ.get("SIGMARL_CACHE")
    existing = next((p for p in (Path(cache), *Path(cache).parents) if p.exists()), None) if cache else None
    if existing is not None and not existing.is_dir():
        raise SigmarlError(f"SIGMARL_CACHE={cache}: {existing} is a file, not a folder: name a folder, or unset "
                           "it (default ~/.cache/sigmarl)")
