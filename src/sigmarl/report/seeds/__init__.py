"""Seeds and plans: each model-seed's figures and its training curve, where the next seed will
land, `--plan` and `seeds=auto`'s rounds."""
