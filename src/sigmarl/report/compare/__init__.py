"""Comparisons and their verdicts: each variant against its baseline, a factorial study's
interactions, training curves compared, whether the paper's claims reproduce, the findings."""
