"""Table I and its numbers: the cells, composite scores, the table in its formats and its notes,
what the columns are (the study page), the paper's figures, and the statistics over scenarios."""
