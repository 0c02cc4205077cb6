"""Where runs are recorded (`tracking.*`)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class TrackingConfig:
    """Where runs are recorded."""

    tracking_uri: str = ""
    """The MLflow store or server (empty: MLflow's default, a local SQLite mlflow.db)."""
    experiment: str = "sigmarl-ablation"
    """The experiment's name; also names runs/<experiment>/ and reports/<experiment>/."""
    enabled: bool = True
    """false: no tracker; the run folders are the only record."""
    backend: str = "mlflow"
    """mlflow, or package.module:Class naming a sigmarl.tracking.Tracker of your own."""
