"""The report's sections, one module per group a reader sees (`table`, `seeds`, `compare`,
`exports`), each holding its `Section`s (`report.draft`); `build.SECTIONS` lists them in order."""
