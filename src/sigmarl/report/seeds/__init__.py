"""Seeds and plans: each model-seed's figures, where the next seed will land, `--plan` and
`seeds=auto`'s rounds."""
