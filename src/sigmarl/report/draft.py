"""The seam of the report: a `Section` is one part of it (a name, the files it may write and what
each holds, when it writes them, the function that builds them from a `Draft`), and
`build.SECTIONS` lists them in order. A section writes through `Draft.write` (or `Draft.file`
for a figure) and leaves on the draft what later sections or the caller need; a file it does
not declare is refused, so the reference page drawn from the declarations lists every file a
report can hold.
"""

from __future__ import annotations

import json
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path

import pandas as pd

from sigmarl.ablation import flags_of, paper_model
from sigmarl.errors import SigmarlError
from sigmarl.report.compare.verdicts import Design
from sigmarl.report.tables import ResultTable

# Fixed formatting of every CSV's floats: the same rows give byte-identical files.
FLOAT_FORMAT = "%.10g"


@dataclass(frozen=True)
class BuildOptions:
    """What `build_report` draws and where.

    out_dir: the folder the files go into; models: the columns, in order (default: every model
    in the rows, in `order`); trim: drop each evaluation's best and worst simulation from the
    collision rates; compare_paper: the paper's numbers in parentheses; ci: 95% bootstrap
    intervals in the table; order: the study's labels in declared order; baseline: what every
    other column is compared with (default M0, or the first column); design: the verdicts'
    study parameters (default: the models against the baseline on CR_total); imported: rows of
    policies trained by the paper's own code (`sigmarl evaluate paper:M<k>`), read only by the
    `paper_policies` section, never pooled with the rows.
    """

    out_dir: Path
    models: list[str] | None = None
    trim: bool = False
    compare_paper: bool = False
    latex: bool = False
    ci: bool = False
    figures: bool = True
    extra_notes: tuple[str, ...] = ()
    order: list[str] | None = None
    baseline: str | None = None
    design: Design | None = None
    # per column one training config (the study page: what each column changes); defaults: the
    # configuration without overrides; commit: the checkout the report is built at
    configs: dict | None = None
    defaults: object | None = None
    commit: str | None = None
    # label -> seed -> its run folder's provenance records (None: not recorded); None: not read
    provenance: dict | None = None
    imported: pd.DataFrame | None = None


class UndeclaredFile(RuntimeError):
    """A section wrote a file its `Section.files` does not name (a fault of the code, not of input)."""


@dataclass(frozen=True)
class Section:
    """One part of the report.

    name: what the reference calls it; files: each file it may write (a `<part>` in a name
    stands for any text, e.g. `marl_eval_<models>.json`) and what the file holds; build: the
    function of the draft that writes them; when: when it writes them, as the reference reads it
    after "Written" ("with `--latex`"; "" for every report); needs: that condition on the draft
    (None: always built).
    """

    name: str
    files: Mapping[str, str]
    build: Callable[[Draft], None]
    when: str = ""
    needs: Callable[[Draft], bool] | None = None

    def declares(self, name: str) -> bool:
        """Whether `name` is one of this section's files (`<part>`: any text without a slash)."""
        return any(re.fullmatch("".join("[^/]+" if p.startswith("<") else re.escape(p)
                                        for p in re.split(r"(<[^>]+>)", f) if p), name) for f in self.files)


@dataclass
class Draft:
    """The report as its sections build it, and, once they are done, what `build_report` returns."""

    rows: pd.DataFrame
    options: BuildOptions
    curves: pd.DataFrame | None  # model, seed, iteration, reward (None: no training curves read)
    models: list[str] = field(default_factory=list)  # the columns, in order
    cells: list = field(default_factory=list)  # see `cells.cells`
    summary: pd.DataFrame | None = None  # one row per (scenario, model, metric)
    composite: pd.DataFrame | None = None  # scenario, model, CS, note, ci_low, ci_high
    table: ResultTable | None = None
    markdown: str = ""  # table.md, what the command prints
    notes: list[str] = field(default_factory=list)
    improvement: pd.DataFrame | None = None  # see `scores.improvement`
    aggregates: pd.DataFrame | None = None  # see `scores.aggregate_scores`
    statistics: str = ""  # Markdown of the two frames above
    training: pd.DataFrame | None = None  # see `training.training_summary`
    verdicts: pd.DataFrame | None = None  # see `compare.verdicts.verdict_table`
    verdicts_markdown: str = ""
    paths: dict[str, Path] = field(default_factory=dict)  # each file written, by its key
    section: Section | None = None  # the one building now, whose files it may write

    @property
    def baseline(self) -> str | None:
        """The compared-with column, if it is one of the report's."""
        return self.options.baseline if self.options.baseline in self.models else None

    @property
    def design(self) -> Design:
        """The study's verdict design over the report's columns (default: against M0, or the first)."""
        design = self.options.design
        return replace(design, variants=list(self.models)) if design is not None else \
            Design(variants=self.models, baseline="M0" if "M0" in self.models else self.models[0])

    @property
    def paper_models(self) -> dict[str, str | None]:
        """Each column's paper model (M0..M5) by the flags its rows record (their `obs` column, the
        strategies that were on; one declared since was off), None for another design (a strategy
        not declared here)."""
        obs = self.rows.drop_duplicates("model").set_index("model")["obs"].fillna("").astype(str)
        out: dict[str, str | None] = {}
        for m in self.models:
            try:
                out[m] = paper_model(flags_of(obs.get(m, "")))
            except SigmarlError:
                out[m] = None
        return out

    def file(self, key: str, name: str) -> Path:
        """Where the current section's file `name` goes, recorded under `key` (a figure's path)."""
        if self.section is not None and not self.section.declares(name):
            raise UndeclaredFile(f"report section {self.section.name!r} wrote {name!r}, which its "
                                 f"Section.files does not declare ({', '.join(self.section.files)})")
        self.paths[key] = self.options.out_dir / name
        return self.paths[key]

    def write(self, key: str, name: str, content: str | pd.DataFrame | dict | None) -> None:
        """One file of the report: Markdown text, a CSV of a frame (fixed float format, so the
        same rows give the same bytes) or JSON; None or an empty frame writes nothing."""
        if content is None or (isinstance(content, pd.DataFrame) and not len(content)):
            return
        path = self.file(key, name)
        if isinstance(content, pd.DataFrame):
            content.to_csv(path, index=False, float_format=FLOAT_FORMAT, lineterminator="\n")
        elif isinstance(content, dict):
            path.write_text(json.dumps(content, indent=1, allow_nan=False) + "\n", encoding="utf-8")
        else:
            path.write_text(content, encoding="utf-8")


def check_sections(sections: list[Section]) -> None:
    """Every section's name once, and every file declared by one section only."""
    seen: dict[str, str] = {}
    names = [s.name for s in sections]
    if len(set(names)) != len(names):
        raise ValueError(f"report sections named twice: {sorted({n for n in names if names.count(n) > 1})}")
    for section in sections:
        for name in section.files:
            if name in seen:
                raise ValueError(f"report file {name!r} declared by sections {seen[name]!r} and {section.name!r}")
            seen[name] = section.name
