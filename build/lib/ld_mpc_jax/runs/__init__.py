"""Runs: one run loop (workdir, checkpoints, evaluations, reports), offline and online training."""
