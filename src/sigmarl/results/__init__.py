"""What a study left on disk and which of its runs make each column: `folders` reads results
folders (run folders, their evaluation rows and training curves, the paper's own policies'
rows), `columns` says which runs a report shows under each column and which it leaves out.
Both are read by the report command and by `seeds=auto`; neither draws a table."""
