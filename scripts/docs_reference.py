"""The generated parts of the documentation, made from the code at every `mkdocs build`, so
they cannot drift: the command line (from sigmarl's argparse parser), every config key (type,
default and help line, from the config dataclasses), the shipped options of each config group
and the scenarios (from the files of conf/ and their opening comments), the files of a run
folder (from `sigmarl.run`), a report's files (from the sections of `sigmarl.report.build`)
and the floors of the imports (from `sigmarl.floors`). A page asks for one with a marker line, e.g. `<!-- generated: config -->`.

mkdocs.yml loads this file as a hook (`on_page_markdown`); `python scripts/docs_reference.py
NAME` prints one part.
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MARKER = re.compile(r"^<!-- generated: ([a-z-]+) -->$", re.M)


def _cell(text: object) -> str:
    """Text for a table cell: pipes escaped, and `<` outside code spans (else HTML)."""
    parts = str(text).replace("|", "\\|").replace("\n", " ").split("`")
    return "`".join(p if i % 2 else p.replace("<", "&lt;") for i, p in enumerate(parts))


def _argument(action: argparse.Action) -> str:
    name = ", ".join(f"`{o}`" for o in action.option_strings) or f"`{action.metavar or action.dest}`"
    if action.choices and not isinstance(action, argparse._SubParsersAction):
        name += " {" + ", ".join(map(str, action.choices)) + "}"
    elif action.option_strings and action.nargs != 0 and not isinstance(action, argparse._VersionAction):
        name += f" `{action.metavar or action.dest.upper()}`"
    return name


def _arguments(parser: argparse.ArgumentParser) -> list[str]:
    rows = ["| argument | what it does |", "|---|---|"]
    for action in parser._actions:
        if isinstance(action, (argparse._HelpAction, argparse._SubParsersAction)):
            continue
        help_text = (action.help or "") % {"prog": parser.prog} if action.help else ""
        rows.append(f"| {_cell(_argument(action))} | {_cell(help_text)} |")
    return rows


def cli() -> str:
    """Every command and option, from the parser the command line uses."""
    from sigmarl.cli import build_parser

    parser = build_parser()
    out = [f"`{parser.format_usage().strip().removeprefix('usage: ')}`", "", parser.description or "", "",
           *_arguments(parser), ""]
    commands = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    helps = {c.dest: c.help for c in commands._choices_actions}
    for name, sub in commands.choices.items():
        usage = " ".join(sub.format_usage().split()).removeprefix("usage: ")
        out += [f"## sigmarl {name}", "", helps.get(name) or "", "", f"`{usage}`", "", *_arguments(sub), ""]
    return "\n".join(out)


def config() -> str:
    """Every config group and key: type, default and its help line; top-level keys first."""
    from sigmarl.config.help import key_help

    header = ["| key | type | default | help |", "|---|---|---|---|"]
    keys = key_help()
    out = ["## Top-level keys", "", *header]
    out += [_key_row(k) for k in keys if "." not in k.key and not k.group]
    for group in (k for k in keys if k.group):
        out += ["", f"## `{group.key}`", "", group.help, "", *header]
        out += [_key_row(k) for k in keys if k.key.startswith(group.key + ".") and not k.group]
    return "\n".join(out) + "\n"


def _key_row(k) -> str:
    from sigmarl.config.help import shown

    return f"| `{k.key}` | `{_cell(k.type)}` | `{_cell(shown(k.default))}` | {_cell(k.help)} |"


def run_folder() -> str:
    """The files of a run folder, from their names and comments in `sigmarl.run`."""
    import sigmarl.run

    source = Path(sigmarl.run.__file__).read_text(encoding="utf-8")
    rows = ["| file | what it holds |", "|---|---|"]
    rows += [f"| `{file}` | {_cell(comment)} |"
             for file, comment in re.findall(r'^[A-Z_]+_(?:FILE|META) = "([^"]+)"\s*#\s*(.*)$', source, re.M)]
    return "\n".join(rows) + "\n"


def _leading_comment(path: Path) -> str:
    """A config file's opening comment (after any `# @package` line), as one line."""
    lines = []
    for line in path.read_text(encoding="utf-8").splitlines():
        if not line.startswith("#"):
            break
        if not line.startswith("# @package"):
            lines.append(line.lstrip("# ").strip())
    return " ".join(lines)


def presets() -> str:
    """Every shipped option of each config group, from the files of conf/ and their comments."""
    from sigmarl.paths import conf_dir

    out = []
    for folder in sorted(p for p in conf_dir().iterdir() if p.is_dir() and p.name not in ("hydra", "scenario")):
        files = sorted(folder.glob("*.yaml"))
        out += [f"### `{folder.name}`", "", "| option | what it is |", "|---|---|"]
        out += [f"| `{folder.name}={f.stem}` | {_cell(_leading_comment(f))} |" for f in files]
        out.append("")
    return "\n".join(out)


def scenarios() -> str:
    """Every shipped scenario: its map and agent count, from conf/scenario/; the paper's first."""
    from sigmarl.paths import conf_dir
    from sigmarl.readers import read_yaml

    found = [(f, read_yaml(f, "a scenario")) for f in sorted((conf_dir() / "scenario").glob("*.yaml"))]
    rows = ["| scenario | map | agents | in the paper's Table I | what it is |", "|---|---|---:|---|---|"]
    rows += [f"| `{f.stem}` | `{s.get('map')}` | {s.get('n_agents')} | {'yes' if s.get('paper') else 'no'} | "
             f"{_cell(_leading_comment(f))} |" for f, s in sorted(found, key=lambda fs: not fs[1].get("paper"))]
    return "\n".join(rows) + "\n"


def _room(name: str) -> str:
    """A room as its file or folder in src/sigmarl/ (`errors.py`, `tracking/`, `config/`),
    or in src/ for one outside the package."""
    path = Path(*name.split("."))
    if name == "sigmarl":
        return "`__init__.py`"
    shown = path.relative_to("sigmarl").as_posix() if path.parts[0] == "sigmarl" else f"src/{path.as_posix()}"
    return f"`{shown}/`" if (ROOT / "src" / path).is_dir() else f"`{shown}.py`"


def floors() -> str:
    """The floors of the imports, top first (an import points down the table), and the imports
    allowed up a floor with their reasons, from `sigmarl.floors`."""
    from sigmarl.floors import FLOORS, REPORT_FLOORS, UPWARD

    rows = ["| floor | rooms | what lives here |", "|---|---|---|"]
    rows += [f"| {i} {_cell(f.name)} | {', '.join(_room(r) for r in f.rooms)} | {_cell(f.holds)} |"
             for i, f in reversed(list(enumerate(FLOORS)))]
    up = [f"- `{a}` imports `{b}`: {_cell(why)}" for (a, b), why in UPWARD.items()]
    report = ["| floor inside `report/` | rooms | what lives here |", "|---|---|---|"]
    report += [f"| report {i} {_cell(f.name)} | {', '.join(_room(r) for r in f.rooms)} | {_cell(f.holds)} |"
               for i, f in reversed(list(enumerate(REPORT_FLOORS)))]
    return "\n".join([*rows, "", "Imports up a floor: " + ("none." if not up else f"{len(up)}, each for a reason:"), *up,
                      "", "Inside `report/`, its groups stand on floors of their own, by the same rule "
                      "and with no import up:", "", *report]) + "\n"


def report_files() -> str:
    """A report's files, section by section in the order they are built, from each section's
    declaration (`report.draft.Section`): a file no section declares cannot be written."""
    from sigmarl.report.build import SECTIONS

    out = []
    for section in SECTIONS:
        out += [f"### `{section.name}`", "", f"Written {section.when or 'in every report'}.", "",
                "| file | what it holds |", "|---|---|"]
        out += [f"| `{name}` | {_cell(what)} |" for name, what in section.files.items()]
        out.append("")
    return "\n".join(out)


PARTS = {"cli": cli, "config": config, "run-folder": run_folder, "presets": presets, "scenarios": scenarios,
         "floors": floors, "report-files": report_files}


def expand(markdown: str) -> str:
    """The page with each marker line replaced by its generated part."""
    return MARKER.sub(lambda m: PARTS[m.group(1)]().strip(), markdown)


def on_page_markdown(markdown: str, page, config, files) -> str:  # the mkdocs hook
    return expand(markdown)


if __name__ == "__main__":
    print(PARTS[sys.argv[1]]())
