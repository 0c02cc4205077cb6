"""Compare the same model(s) across two results folders: does a variant agree with a baseline?

Made for validating `ppo.precision=bf16` against the fp32 study (the rule: learning
curves and evaluations over >= 3 seeds must agree within their intervals), and usable for any
variant run as a sweep of its own:

    sigmarl sweep models=[M0] seeds=[0,1,2] ppo.precision=bf16 runs_root=results/bf16-check
    python scripts/compare_folders.py fp32=results/paper-budget bf16=results/bf16-check \\
        --models M0 --out reports/bf16-check

Each folder's models are relabelled "<model> <tag>" and reported together (`build_report`:
table with 95% two-level bootstrap intervals, P(baseline collides less), training summary
and curves). Then, per model, each (scenario, metric) cell and the final training reward
(mean of the last iterations, bootstrapped over seeds) are checked for overlapping intervals;
the script prints the cells that do not overlap and exits 1 if there are any (0: agree).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from sigmarl.cli.report import publish, staged
from sigmarl.errors import SigmarlError
from sigmarl.report.build import BuildOptions, build_report
from sigmarl.results.folders import read_results
from sigmarl.stats import bootstrap as bs


def labelled(root: Path, tag: str, models: list[str]) -> tuple[pd.DataFrame, pd.DataFrame]:
    """`root`'s evaluation rows and curves of `models`, each model renamed "<model> <tag>"."""
    results = read_results(root)
    for note in results.notes:
        print(f"{tag}: {note}", file=sys.stderr)
    rows = results.rows[results.rows["model"].isin(models)].copy()
    missing = [m for m in models if m not in set(rows["model"])]
    if missing:
        raise SigmarlError(f"{root} has no evaluation rows for {', '.join(missing)}")
    curves = results.curves[results.curves["model"].isin(models)].copy()
    rows["model"] = rows["model"] + f" {tag}"
    curves["model"] = curves["model"] + f" {tag}"
    return rows, curves


def reward_interval(rewards: np.ndarray, name: str) -> tuple[float, float, float]:
    """Mean of the seeds' final rewards and its percentile bootstrap interval over seeds."""
    rng = bs.rng_for("compare_folders", name)
    draws = rng.choice(rewards, size=(bs.N_BOOT, len(rewards)), replace=True).mean(axis=1)
    lo, hi = np.quantile(draws, [(1 - bs.LEVEL) / 2, (1 + bs.LEVEL) / 2])
    return float(rewards.mean()), float(lo), float(hi)


def disagreements(summary: pd.DataFrame, training: pd.DataFrame | None, pairs: list[tuple[str, str]]) -> list[str]:
    """Cells (and final rewards) whose intervals do not overlap, one line each."""
    lines = []
    cells = summary.set_index(["scenario", "metric", "model"])
    for base, variant in pairs:
        for (scenario, metric), _ in summary.groupby(["scenario", "metric"], sort=False):
            a, b = cells.loc[(scenario, metric, base)], cells.loc[(scenario, metric, variant)]
            if a["ci_high"] < b["ci_low"] or b["ci_high"] < a["ci_low"]:
                lines.append(f"{scenario} {metric}: {base} {a['mean']:.4g} [{a['ci_low']:.4g}, {a['ci_high']:.4g}] vs "
                             f"{variant} {b['mean']:.4g} [{b['ci_low']:.4g}, {b['ci_high']:.4g}]")
        if training is not None and len(training):
            got = {}
            for model in (base, variant):
                rewards = training.loc[training["model"] == model, "reward_last"].to_numpy(float)
                if len(rewards):
                    got[model] = reward_interval(rewards, model)
            if len(got) == 2:
                (ma, la, ha), (mb, lb, hb) = got[base], got[variant]
                if ha < lb or hb < la:
                    lines.append(f"final training reward: {base} {ma:.3g} [{la:.3g}, {ha:.3g}] vs "
                                 f"{variant} {mb:.3g} [{lb:.3g}, {hb:.3g}]")
    return lines


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("baseline", help="TAG=FOLDER of the baseline, e.g. fp32=results/paper-budget")
    p.add_argument("variant", help="TAG=FOLDER of the variant, e.g. bf16=results/bf16-check")
    p.add_argument("--models", default="M0", help="comma-separated models to compare (default M0)")
    p.add_argument("--out", default="reports/compare", help="output folder of the joint report")
    p.add_argument("--no-figures", action="store_true")
    args = p.parse_args(argv)
    try:
        sides = []
        for spec in (args.baseline, args.variant):
            tag, sep, folder = spec.partition("=")
            if not sep or not tag or not folder:
                raise SigmarlError(f"expected TAG=FOLDER, got {spec!r}")
            sides.append((tag, Path(folder)))
        if sides[0][0] == sides[1][0]:
            raise SigmarlError("the two folders need different tags")
        models = [m for m in args.models.split(",") if m]
        parts = [labelled(folder, tag, models) for tag, folder in sides]
        rows = pd.concat([r for r, _ in parts], ignore_index=True)
        curves = pd.concat([c for _, c in parts], ignore_index=True)
        order = [f"{m} {tag}" for m in models for tag, _ in sides]
        out = Path(args.out)
        with staged(out) as staging:  # files appear in `out` only once all are written
            report = build_report(rows, BuildOptions(out_dir=staging, models=order, ci=True,
                                                     figures=not args.no_figures),
                                  curves if len(curves) else None)
            publish(report, staging, out)
    except SigmarlError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    print(report.markdown)
    print(report.statistics)
    pairs = [(f"{m} {sides[0][0]}", f"{m} {sides[1][0]}") for m in models]
    lines = disagreements(report.summary, report.training, pairs)
    if lines:
        print(f"{len(lines)} interval(s) do not overlap:\n  " + "\n  ".join(lines))
        return 1
    print(f"agree: every cell's and the final reward's 95% intervals overlap ({', '.join(models)})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
