"""Exports for other tools and eyes: the figures (matplotlib, imported on use) and marl-eval's JSON."""
