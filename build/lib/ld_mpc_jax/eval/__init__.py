"""Evaluation: lockstep rollouts, policy x split x seed grids, diagnostics, run files and plots."""
