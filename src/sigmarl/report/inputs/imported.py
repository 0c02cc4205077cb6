"""Evaluation rows of policies trained by the paper's own code (`sigmarl evaluate paper:M<k>`),
read for the report's `paper_policies` section, never pooled with a study's rows.

Layout, as results/paper-policies/ is committed: `<label>/<rules>/evaluation_rows.csv` (each
with its `evaluation.json`). `sigmarl report --from <results>/<study> --compare-paper` reads the
folder `paper-policies` beside the study's folder, where there is one.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from sigmarl.errors import SigmarlError
from sigmarl.params import VEHICLE
from sigmarl.rows import check_rows
from sigmarl.run import ROWS_FILE

FOLDER = "paper-policies"  # beside a results folder: the paper's own policies' rows
# the paper's speed command range: under its drag dynamics a speed may pass ours (0.8) in a transient
PAPER_TOP_SPEED = 1.0


def imported_folder_beside(root: Path) -> Path | None:
    """`<parent of root>/paper-policies`, where it exists."""
    folder = Path(root).resolve().parent / FOLDER
    return folder if folder.is_dir() else None


def read_imported(folder: Path) -> pd.DataFrame:
    """Every `<label>/<rules>/evaluation_rows.csv` under `folder`, checked, marked imported
    (`source`), in one frame (empty where there are none)."""
    frames = []
    for path in sorted(Path(folder).glob(f"*/*/{ROWS_FILE}")):
        try:
            rows = pd.read_csv(path, float_precision="round_trip")
        except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as e:
            raise SigmarlError(f"{path} is not a readable CSV: {str(e).splitlines()[0]}") from e
        missing = [c for c in ("model", "obs", "seed", "rules", "source") if c not in rows.columns]
        if missing:
            raise SigmarlError(f"{path}: rows of an imported policy lack the column(s) {', '.join(missing)}")
        paper = set(rows["rules"].astype(str)) == {"paper"}
        frames.append(check_rows(rows, path, PAPER_TOP_SPEED if paper else VEHICLE.max_speed))
    return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()
