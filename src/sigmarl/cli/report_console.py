"""What `sigmarl report` prints: a short console report (Table I's headline, the verdict counts,
where the files are; at most MAX_LINES lines), or with --verbose the full text of its files."""

from __future__ import annotations

from collections import Counter

from sigmarl.metrics import HEADLINE, TABLE_DIGITS, shown_unit
from sigmarl.report.draft import Draft

MAX_LINES = 40
VERDICT_ORDER = ("better", "worse", "equivalent", "undecided")
LEFT_OUT_LINES = 5  # notes of runs or rows left out, at most (then a count)
_OTHER_LINES = 17  # lines the console report spends besides the table's scenario rows


def console_text(report: Draft, verbose: bool = False) -> str:
    """The console's report: short, or (verbose) the text it printed before it was shortened."""
    return _full(report) if verbose else "\n".join(_short(report))


def _short(report: Draft) -> list[str]:
    out_dir = _folder(report)
    lines = [f"{HEADLINE} ({shown_unit(HEADLINE)}) per scenario and column, mean over seeds; the whole table and its notes: "
             f"{out_dir}/table.md", ""]
    lines += _headline_table(report)
    if (verdicts := _verdict_counts(report)) is not None:
        lines += ["", verdicts]
    # what the report left out is said here too: a reader must not miss a missing seed
    left_out = [n for n in report.notes if "left out" in n]
    if left_out:
        lines += ["", *left_out[:LEFT_OUT_LINES]]
        if len(left_out) > LEFT_OUT_LINES:
            lines.append(f"... and {len(left_out) - LEFT_OUT_LINES} more left out: table.md's notes")
    names = [p.name for p in report.paths.values()]
    lines += ["", f"{len(names)} files in {out_dir}/: {', '.join(names[:8])}{', ...' if len(names) > 8 else ''}",
              "the full text of table.md, the statistics and verdicts: sigmarl report ... --verbose"]
    return lines


def _headline_table(report: Draft) -> list[str]:
    """Table I's headline as a Markdown table: a row per scenario, a column per model; at most
    as many rows as keep the report within MAX_LINES."""
    summary = report.summary
    if summary is None or not len(summary):
        return ["(no rows to tabulate)"]
    rows = summary[summary["metric"] == HEADLINE]
    models = [m for m in report.models if m in set(rows["model"])] or list(dict.fromkeys(rows["model"]))
    scenarios = list(dict.fromkeys(rows["scenario"]))
    room = MAX_LINES - _OTHER_LINES - 2
    shown, rest = scenarios[:room], scenarios[room:]
    means = {(r.scenario, r.model): r.mean for r in rows.itertuples()}  # in the table's units (%)
    table = ["| scenario | " + " | ".join(models) + " |", "|---|" + "---:|" * len(models)]
    for name in shown:
        cells = [f"{means[(name, m)]:.{TABLE_DIGITS}f}" if (name, m) in means else "–" for m in models]
        table.append(f"| {name} | " + " | ".join(cells) + " |")
    if rest:
        table[-1] += f"  (and {len(rest)} more scenarios in table.md)"
    return table


def _verdict_counts(report: Draft) -> str | None:
    verdicts = report.verdicts
    if verdicts is None or not len(verdicts):
        return None
    counts = Counter(str(v) for v in verdicts["verdict"])
    known = [f"{counts.pop(v)} {v}" for v in VERDICT_ORDER if v in counts]
    known += [f"{n} {v}" for v, n in counts.items()]
    return (f"verdicts, {len(verdicts)} comparisons with the baseline (per scenario and metric): "
            f"{', '.join(known)}; each in verdicts.md")


def _folder(report: Draft) -> str:
    paths = list(report.paths.values())
    return str(paths[0].parent) if paths else str(report.options.out_dir)


def _full(report: Draft) -> str:
    """The table, its notes, the statistics, the training summary, the curves' and the
    metrics' verdicts, and the files written, as the command printed them before."""
    parts = [report.markdown]
    if report.statistics:
        parts.append(report.statistics)
    for key in ("training_md", "curve_verdicts_md"):
        if key in report.paths:
            parts.append(report.paths[key].read_text(encoding="utf-8"))
    if report.verdicts_markdown:
        parts.append(report.verdicts_markdown)
    parts.append("wrote " + ", ".join(str(p) for p in report.paths.values()))
    return "\n".join(parts)
