"""`sigmarl sweep seeds=auto`: seeds added where they decide something.

The sweep runs in rounds. The first trains the study's own seeds (`study.seeds`, at least
two) for every variant, raised to the first look at which the permutation test can show a
difference (`sigmarl.report.plan.first_decidable_look`: at 5 against 5 seeds its smallest p,
2/252 = 0.0079, lies above the design's level of that look, so from 3 seeds up to 10 and one
comparison the first look is at 6 seeds; with Holm over 20 comparisons at 7). After each round every comparison (variant against the baseline, per
scenario and decided metric) is decided again under a group-sequential design that keeps the
error of the repeated looks at the study's level (`sigmarl.report.plan`), and each
variant with an undecided comparison gets one more seed (the baseline too, when it needs
one), up to `study.max_seeds`. It stops when every comparison is decided or the cap is reached.

Every look is recorded, whole or not at all, in `<runs_root>/seeds_auto.json`: the design,
the seeds each variant has, the verdicts that are final, and why each seed was added. A sweep
killed at any instant and started again goes on from that record and from the run folders
(a round's seeds that finished are not trained again), and never repeats a look.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

import pandas as pd

from sigmarl.errors import SigmarlError
from sigmarl.readers import read_json
from sigmarl.report.compare.verdicts import design_of
from sigmarl.report.plan import first_decidable_look, key, next_round
from sigmarl.results.folders import RunFolder, rows_of
from sigmarl.run import Run, write_atomic
from sigmarl.sweep import launch, plan_sweep

RECORD = "seeds_auto.json"


def run_auto(user: Sequence[str]) -> int:
    plan = plan_sweep(user)
    study = plan.study
    labels = plan.labels
    n_start = len({j.seed for j in plan.jobs})
    if n_start < 2:
        raise SigmarlError("seeds=auto starts from the study's seeds and needs at least two: give "
                           "study.seeds=[0,1,2] (the seeds of its first round)")
    if study.baseline not in labels:
        raise SigmarlError(f"seeds=auto compares with the baseline {study.baseline}, which is not among "
                           f"the variants swept ({', '.join(labels)})")
    design = design_of(study, labels)
    family = len(design.compared) * len(study.scenarios) * len(design.metrics)
    if family == 0:  # nothing to decide: seeds would be trained for no verdict
        raise SigmarlError(f"seeds=auto has nothing to compare: {_empty_family(design, study)}; sweep "
                           "at least one variant beside the baseline with a decided metric and a scenario")
    first = first_decidable_look(n_start, design.max_seeds, design.alpha, family)
    path = Path(plan.config.runs_root) / RECORD
    identity = {"study": study.name, "variants": labels, "baseline": design.baseline,
                "metrics": list(design.metrics), "margins": design.margins, "alpha": design.alpha,
                "n_start": n_start, "first_look": first, "max_seeds": design.max_seeds}
    record = _load(path, identity)
    if record is None:
        record = {**identity, "seeds": _first_seeds(plan.jobs, first), "previous": {}, "looks": [], "done": False}
    if first > n_start and not record["looks"]:
        print(f"seeds=auto: the first look is at {first} seeds per model (at fewer the permutation test "
              f"cannot show a difference at the design's level over {family} comparison(s))")
    while True:
        round_plan = plan_sweep(user, seeds_by_label=record["seeds"])
        if record["done"]:
            print(f"seeds=auto: finished earlier (see {path}); {_summary(record)}")
            return 0
        rc = launch(round_plan)
        if rc != 0:
            print(f"seeds=auto: a job of this round did not finish; run the same command again to go on "
                  f"({path} holds the rounds so far)")
            return rc
        rows = _rows(round_plan)
        look = next_round(rows, design, first, record["previous"])
        decided = look.verdicts[look.verdicts["verdict"] != "undecided"]
        for _, r in decided.iterrows():
            record["previous"][key(r["scenario"], r["metric"], r["variant"])] = r["verdict"]
        record["looks"].append({
            "seeds": {label: len(s) for label, s in record["seeds"].items()},
            "verdicts": {key(r.scenario, r.metric, r.variant): r.verdict for r in look.verdicts.itertuples()},
            "reasons": look.reasons,
        })
        for label, k in look.add.items():
            have = record["seeds"].setdefault(label, [])
            have += [max(have, default=-1) + 1 + i for i in range(k)]
        record["done"] = look.done
        write_atomic(path, json.dumps(record, indent=1, sort_keys=True) + "\n")
        print("seeds=auto, look {}: {}".format(len(record["looks"]), "; ".join(look.reasons) or "nothing to add"))
        if look.done:
            print(f"seeds=auto: done; {_summary(record)}; the record is {path}")
            return 0


def _empty_family(design, study) -> str:
    """Why a study's family of comparisons is empty, in words."""
    parts = [f"{len(design.compared)} variant(s) beside the baseline {design.baseline}",
             f"{len(design.metrics)} metric(s)", f"{len(study.scenarios)} scenario(s)"]
    return ", ".join(parts)


def _first_seeds(jobs, first: int) -> dict[str, list[int]]:
    """Each variant's seeds of the first round: the study's, then the next ones up to `first`."""
    out = {}
    for j in jobs:
        out.setdefault(j.label, set()).add(j.seed)
    for label, seeds in out.items():
        out[label] = sorted(seeds) + [max(seeds) + 1 + i for i in range(first - len(seeds))]
    return out


def _load(path: Path, identity: dict) -> dict | None:
    if not path.is_file():
        return None
    fix = "move it away to start seeds=auto afresh"
    record = read_json(path, "the seeds=auto record", fix,
                       {"seeds": dict, "previous": dict, "looks": list, "done": bool})
    for label, seeds in record["seeds"].items():
        if not isinstance(seeds, list) or not all(isinstance(s, int) and not isinstance(s, bool) for s in seeds):
            raise SigmarlError(f"{path}: the seeds of {label!r} must be a list of whole numbers; {fix}")
    if not all(isinstance(look, dict) and isinstance(look.get("verdicts"), dict) for look in record["looks"]):
        raise SigmarlError(f"{path}: each look must be a JSON object with its verdicts; {fix}")
    if {k: record.get(k) for k in identity} != json.loads(json.dumps(identity)):
        raise SigmarlError(f"{path} records seeds=auto under another design (study, variants, metrics, "
                           "margins, seeds or cap); move it away, or sweep with the same settings")
    return record


def _rows(plan) -> pd.DataFrame:
    """The evaluation rows of the plan's run folders, checked as `report --from` checks them."""
    missing = [j.key for j in plan.jobs if not Run(j.run_dir).rows_file.is_file()]
    if missing:  # a look without a seed's rows would decide on fewer seeds than recorded
        raise SigmarlError(f"seeds=auto: {', '.join(missing[:3])} finished without its evaluation rows; "
                           "run the same command again (the sweep evaluates it again)")
    return pd.concat([rows_of(RunFolder(j.label, j.seed, Path(j.run_dir))) for j in plan.jobs], ignore_index=True)


def _summary(record: dict) -> str:
    last = record["looks"][-1]["verdicts"] if record["looks"] else {}
    counts = pd.Series(list(last.values()), dtype=object).value_counts().to_dict() if last else {}
    seeds = ", ".join(f"{label} {len(s)}" for label, s in record["seeds"].items())
    return f"verdicts {counts or 'none yet'}; seeds {seeds}"
