"""What a report is built from: the run folders, which runs belong to which column, one
training config per column."""
