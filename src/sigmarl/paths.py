"""Where the Hydra config tree lives."""

from __future__ import annotations

import os
from pathlib import Path


def conf_dir() -> Path:
    """conf/ of the checkout (editable install) or $SIGMARL_CONF."""
    if env := os.environ.get("SIGMARL_CONF"):
        return Path(env).resolve()
    return (Path(__file__).resolve().parents[2] / "conf").resolve()
