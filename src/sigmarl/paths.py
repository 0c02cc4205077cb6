"""Where the Hydra config tree lives.

The tree is kept at the top of the repository (`conf/`) and reached from the package through
the symlink `src/sigmarl/conf -> ../../conf`: the same path serves a checkout on PYTHONPATH, an
editable install and a wheel (building follows the link and ships real files as
`sigmarl/conf/`).
"""

from __future__ import annotations

import os
from pathlib import Path


def conf_dir() -> Path:
    """The package's conf/ (see above), or $SIGMARL_CONF."""
    if env := os.environ.get("SIGMARL_CONF"):
        return Path(env).resolve()
    return (Path(__file__).resolve().parent / "conf").resolve()


def ensure_writable(folder: Path, what: str) -> None:
    """Create `folder` and check that a file can be written there, before any work; otherwise
    a SigmarlError naming it and `what` to do ("choose another run_dir=...")."""
    import tempfile

    from sigmarl.errors import SigmarlError

    try:
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError as e:
        raise SigmarlError(f"{folder} is not writable ({e.strerror}); {what}") from e
