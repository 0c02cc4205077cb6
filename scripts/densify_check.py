"""How much the emulation of the paper's raw test-map vertices moves a `rules=paper` policy's rows.

The paper's hand-drawn test maps had center-line vertices about 0.1 m apart; we know them only
simplified to within 2 mm, so `rules.raw_center_line` re-cuts every segment longer than 0.2 m
into pieces of at most 0.1 m (`env.paper_rules.densify`: a 0.216 m segment becomes three of
0.072 m). This evaluates a checkpoint under that emulation and under another one, pieces as close
to 0.1 m as possible (two of 0.108 m), with the evaluation protocol, and prints both:

    python scripts/densify_check.py results/paper-rules/M0-paper/seed0/best.pt

With `--contacts FILE` (a contact log of `scripts/lane_contacts.py --out FILE`) it also prints,
for the five places with the most contacts, the raw vertex spacing over the 0.7 m ahead of them.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import torch

from sigmarl.env import paper_rules
from sigmarl.errors import SigmarlError
from sigmarl.evaluation.rollout import evaluate_policy
from sigmarl.maps import load_map, scenario_map_config
from sigmarl.scenarios import scenario
from sigmarl.training.checkpoint import config_of
from sigmarl.training.loop import load_policy

SHIPPED = paper_rules.densify
CENTER_SPACING = 0.08  # m between the route bank's center points (the contact log's `index`)


def densify_nearest(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """`paper_rules.densify` with every segment cut into the number of pieces nearest to 0.1 m each."""
    length = np.linalg.norm(np.diff(points, axis=0), axis=-1)
    return paper_rules.cut(points, np.maximum(1, np.round(length / 0.1)).astype(int))


def rates(checkpoint: Path, scenarios: list[str]) -> pd.DataFrame:
    rows = []
    for name, cut in (("shipped (ceil)", SHIPPED), ("nearest 0.1 m", densify_nearest)):
        paper_rules.densify = cut  # the emulation is looked up at each scenario's construction
        try:
            for s in scenarios:
                n = scenario(s).n_agents
                actor, state = load_policy(checkpoint, n_agents=n)
                r = evaluate_policy(actor, config_of(state, checkpoint), s, n_agents=n, progress=False)
                rows.append({"emulation": name, "scenario": s, **(100 * r[["CR_AA", "CR_AL", "CR_total"]].mean()).round(2),
                             "CD": round(r["CD"].mean(), 2), "AS": round(r["AS"].mean(), 3)})
        finally:
            paper_rules.densify = SHIPPED
    return pd.DataFrame(rows)


def spacing_at_contacts(contacts: pd.DataFrame, scenario_name: str, top: int = 5) -> pd.DataFrame:
    """The shipped raw center line's vertex spacing over the 0.7 m ahead (the reference points reach
    about 0.6 m) of the busiest contact places."""
    road_map = load_map(scenario_map_config(scenario_name))
    places = contacts.groupby(["route", "index"]).size().sort_values(ascending=False)
    out, seen = [], set()
    for (route, index), count in places.items():
        if any(r == route and abs(i - index) <= 3 for r, i in seen):
            continue  # the same place, one center point on
        seen.add((route, index))
        line = paper_rules._raw_center(road_map, road_map.routes[route])
        seg = np.linalg.norm(np.diff(line, axis=0), axis=1)
        start = np.concatenate([[0], np.cumsum(seg)])[:-1]
        s = index * CENTER_SPACING
        ahead = seg[(start >= s - 0.1) & (start < s + 0.7)]
        out.append({"route": route, "index": index, "contacts": count, "spacing_ahead_m": " ".join(f"{x:.3f}" for x in ahead)})
        if len(out) == top:
            break
    return pd.DataFrame(out)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("checkpoint", type=Path)
    p.add_argument("--scenarios", nargs="+", default=["Intersection", "On-Ramp", "Roundabout"])
    p.add_argument("--contacts", type=Path, help="a contact log of scripts/lane_contacts.py --out")
    p.add_argument("--contacts-scenario", default="Roundabout")
    a = p.parse_args()
    torch.set_num_threads(1)
    try:
        if a.contacts:
            print(spacing_at_contacts(pd.read_csv(a.contacts), a.contacts_scenario).to_string(index=False))
        print(rates(a.checkpoint, a.scenarios).to_string(index=False))
    except SigmarlError as e:
        sys.exit(f"densify_check: error: {e}")


if __name__ == "__main__":
    main()
