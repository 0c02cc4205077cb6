"""What a report leaves out, and why: every run of the study's variants without evaluation rows
in the report is named as failed (with its error), trained but not evaluated, unfinished, or
never run. A failed run, or a declared variant whose runs have no rows, ends the report in one
line unless it is told to go on (`--partial`); then each is a note of the table."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

from sigmarl.errors import SigmarlError
from sigmarl.run import Run


@dataclass(frozen=True)
class LeftOut:
    label: str
    seed: int | None  # None: the variant has no run folder at all
    why: str  # "failed: <error>", "trained, not evaluated yet", ...
    failed: bool = False

    def __str__(self) -> str:
        return f"{self.label}{'' if self.seed is None else f' seed {self.seed}'} {self.why}"


def run_state(path: Path) -> tuple[str, bool]:
    """Why a run folder has no rows in the report (its files alone), and whether it failed."""
    run = Run(path)
    if (failure := run.failure()) is not None:
        return f"failed: {failure}", True
    if run.rows_file.is_file():
        return "evaluated, but its rows are not in the report's source", False
    if run.final_file.is_file():
        return "trained, not evaluated yet", False
    if run.resume_file.is_file() or run.metrics_file.is_file():
        return f"not evaluated yet, training unfinished (no {run.final_file.name})", False
    return "not evaluated yet, training never started", False


def belongs(label: str, variants: Iterable[str]) -> bool:
    """A label of the study: one of its variants (one a command-line sweep derived from it,
    M0_hidden-64-64, is its sweep's own)."""
    return label in set(variants)


def left_out(variants: Sequence[str], reported: set[tuple[str, int]],
             folders: Iterable[tuple[str, int, Path]], where: str, declared: bool = True) -> list[LeftOut]:
    """The study's runs not in the report: each run folder (label, seed, path) of one of
    `variants` whose (label, seed) has no rows in it and, where the study `declared` them, each
    variant that has neither rows nor a run folder (`where`: where its folders were looked for)."""
    out, seen = [], set()
    for label, seed, path in folders:
        if not belongs(label, variants):
            continue
        seen.add(label)
        if (label, seed) not in reported:
            why, failed = run_state(path)
            out.append(LeftOut(label, seed, why, failed))
    if declared:
        have = {label for label, _ in reported} | seen
        never = [v for v in variants if not any(belongs(label, [v]) for label in have)]
        if never:
            out.append(LeftOut(", ".join(never), None, f"not run (no rows, no run folder in {where})"))
    return out


def check(declared: Sequence[str], reported: set[tuple[str, int]], missing: list[LeftOut],
          study: str, partial: bool) -> None:
    """What the report leaves out, refused in one line unless `partial` where a run
    failed, or a declared variant has run folders but no rows (unfinished, not evaluated). A
    variant never run (no folder, no rows: e.g. `sweep models=[...]` picked others) is a note."""
    started = {m.label for m in missing if m.seed is not None}
    rowless = [v for v in declared if v in started and not any(belongs(label, [v]) for label, _ in reported)]
    failed = [m for m in missing if m.failed]
    if (rowless or failed) and not partial:
        what = []
        if rowless:
            what.append(f"{', '.join(rowless)} of study {study!r} {'has' if len(rowless) == 1 else 'have'} "
                        "no evaluation rows")
        if failed:
            what.append(f"{len(failed)} run(s) failed")
        raise SigmarlError(f"{' and '.join(what)}: {'; '.join(map(str, missing))}. Fix it and run the "
                           "sweep again, or give --partial to report the rest")
