"""The floors of the house: sigmarl's modules in layers, ground first, and every import (at
module level or inside a function, `if TYPE_CHECKING:` included) points to its own floor or one
below. A lazy import buys start-up time; it never lets a low room reach up.

Data only, read twice: `tests/test_import_graph.py` holds the code to it (no circle, no import
up a floor unless `UPWARD` names it with its reason) and the architecture page's floor table
is drawn from it (`scripts/docs_reference.py`).

A room is a module or a package (all of its modules); the longest name that holds a module
decides its floor. The top package, `sigmarl`, is a room of its own module only.
"""

from __future__ import annotations

from typing import NamedTuple


class Floor(NamedTuple):
    name: str
    holds: str  # what lives here, for the architecture page
    rooms: tuple[str, ...]


FLOORS: tuple[Floor, ...] = (
    Floor("ground", "the errors a user can cause, the run folder, crash points, a job's resources and "
          "progress lines, the paper's vocabulary and constants, the metrics' records, the study-free "
          "statistics, and the floors' own list",
          ("sigmarl", "sigmarl.errors", "sigmarl.crash", "sigmarl.run",
           "sigmarl.resources", "sigmarl.progress", "sigmarl.ablation", "sigmarl.params", "sigmarl.metrics",
           "sigmarl.stats", "sigmarl.floors")),
    Floor("config records", "the structured-config schema and its groups' records, one module a group; "
          "what values a key takes; every key's help line; \"did you mean\"",
          ("sigmarl.config",)),
    Floor("readers and identity", "the checked readers of damageable files, evaluation rows' checks, "
          "where the config tree is, the scenarios, a run's identity, what makes two evaluations "
          "interchangeable, what a policy reads, which folders are sigmarl's to write",
          ("sigmarl.readers", "sigmarl.rows", "sigmarl.paths", "sigmarl.scenarios", "sigmarl.identity",
           "sigmarl.eval_key", "sigmarl.policy_input", "sigmarl.run_owner")),
    Floor("tracking", "where runs are recorded: the tracker seam and the MLflow tracker",
          ("sigmarl.tracking",)),
    Floor("maps", "road maps: the model, routes, loaders and builders, a map by name",
          ("sigmarl.maps",)),
    Floor("env", "the VMAS scenario and its tensor kernels", ("sigmarl.env",)),
    Floor("composition", "a command's config composed by Hydra and checked whole (its scenarios' "
          "maps loaded to count their room)",
          ("sigmarl.compose",)),
    Floor("training", "MAPPO: networks, losses, the loop, checkpoints, metrics.csv", ("sigmarl.training",)),
    Floor("evaluation", "test-mode rollouts, the evaluation protocol, animations", ("sigmarl.evaluation",)),
    Floor("results", "what a study left on disk, read without MLflow: results folders, their run folders' "
          "rows and curves, the paper's policies' rows; which runs make each column and which are left out",
          ("sigmarl.results",)),
    Floor("sweep and report", "the multirun and the report (rows in, tables, verdicts and files out), side by side",
          ("sigmarl.sweep", "sigmarl.report")),
    Floor("commands", "the command line and what only it drives: the report command (its sources, staging "
          "and tracker run) and what it prints, `seeds=auto`, shell completion, Hydra's search-path plugin",
          ("sigmarl.cli", "sigmarl.__main__", "hydra_plugins.sigmarl_config_dirs")),
)

# (importing module, imported module) -> why it may import up a floor; at most three.
UPWARD: dict[tuple[str, str], str] = {}

# Inside the report (one room of the floors above), its groups in floors of their own, by the
# same rule: a module imports from its own group's floor or one below.
REPORT_FLOORS: tuple[Floor, ...] = (
    Floor("table", "Table I: its cells and composite scores, the scores over scenarios, the table in its "
          "formats with its notes and the paper's figures, the study page, the training curves' summary",
          ("sigmarl.report.cells", "sigmarl.report.scores", "sigmarl.report.tables", "sigmarl.report.study",
           "sigmarl.report.training")),
    Floor("compare", "verdicts, interactions, curves compared, replication, findings",
          ("sigmarl.report.compare",)),
    Floor("seeds", "each seed's figures, the next seed, `--plan`, `seeds=auto`'s rounds",
          ("sigmarl.report.seeds", "sigmarl.report.plan")),
    Floor("exports", "figures and marl-eval's JSON", ("sigmarl.report.figures", "sigmarl.report.marl_eval")),
    Floor("seam", "`Section`, `Draft`, `BuildOptions`", ("sigmarl.report.draft",)),
    Floor("sections", "every group's sections", ("sigmarl.report.sections",)),
    Floor("build", "`build_report` and its registry of sections, the package's own names (`__init__.py`)",
          ("sigmarl.report.build", "sigmarl.report")),
)


def floor_of(module: str, floors: tuple[Floor, ...] = FLOORS) -> int | None:
    """The index in `floors` of the floor `module` is on (None: on none)."""
    best, found = -1, None
    for i, floor in enumerate(floors):
        for room in floor.rooms:
            holds = module == room or (room != "sigmarl" and module.startswith(room + "."))
            if holds and len(room) > best:
                best, found = len(room), i
    return found
