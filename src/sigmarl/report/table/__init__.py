"""Table I and its numbers: the cells, composite scores, the table in its formats and its notes,
what the columns are (the study page), the paper's figures, the statistics over scenarios and
the training curves' summary."""
