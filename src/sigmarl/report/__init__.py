"""The study's report: evaluation rows in, Table I, comparisons, seeds, figures and exports out.

`build.SECTIONS` lists the sections that write the files (`draft.Section`, declared in
`sections`); the figures (`figures`, matplotlib) are imported on use, since matplotlib is slow
to load.
"""

from sigmarl.report.build import BuildOptions, Report, build_report

__all__ = ["BuildOptions", "Report", "build_report"]
