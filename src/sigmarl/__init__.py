"""sigmarl: the SigmaRL observation-design ablation study, end to end."""

import os as _os

# A run must not reach the network behind the user's back: MLflow 3 sends usage telemetry
# (a DNS lookup and HTTPS posts to its telemetry host) unless this is set before it is
# imported. This is the package's first module, so every entry point passes here first.
_os.environ.setdefault("MLFLOW_DISABLE_TELEMETRY", "true")

__version__ = "0.1.0"
