"""Creating a new SQLite tracking store: MLflow's own creation against a copy of the template.

Every `sigmarl` command that records to a store that does not exist yet creates it. MLflow
creates a store by running its whole chain of schema migrations; sigmarl copies an empty store
of the same MLflow version that it kept the first time (`tracking/store.py`). Both go through
`sigmarl.tracking.connect` in this process, in alternating rounds (so that load from other
processes hits them alike), each on a new folder:
- baseline: an empty cache folder, so MLflow creates the store (and it is kept as template);
- current: the cache holding the template, so the store is a copy of it.
The table gives each one's median and the ratio baseline / current.

Run: python benchmarks/bench_store.py [--rounds 5]
"""

from __future__ import annotations

import argparse
import logging
import os
import statistics
import tempfile
import time
from pathlib import Path

from bench_startup import cpu_name  # benchmarks/ is on sys.path when run as a script

from sigmarl.compose import compose_config
from sigmarl.tracking import connect


def create(db: Path, cache: Path) -> float:
    os.environ["SIGMARL_CACHE"] = str(cache)
    cfg = compose_config([f"tracking.tracking_uri=sqlite:///{db}"])
    t0 = time.perf_counter()
    connect(cfg).search_experiments()
    return time.perf_counter() - t0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--rounds", type=int, default=5)
    args = parser.parse_args()
    logging.disable(logging.INFO)
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        warm = root / "warm-cache"
        create(root / "warm-up" / "mlflow.db", warm)  # imports, and the template for `current`
        own, copied = [], []
        for k in range(args.rounds):
            own.append(create(root / f"own{k}" / "mlflow.db", root / f"cold-cache{k}"))
            copied.append(create(root / f"copy{k}" / "mlflow.db", warm))
    base, cur = statistics.median(own), statistics.median(copied)
    print(f"{cpu_name()}, {args.rounds} rounds, median per new store")
    print("| store creation | seconds |")
    print("|---|---:|")
    print(f"| MLflow creates it (baseline) | {base:.2f} |")
    print(f"| copy of the template (current) | {cur:.2f} |")
    print(f"ratio baseline / current: {base / cur:.1f}x")


if __name__ == "__main__":
    main()
