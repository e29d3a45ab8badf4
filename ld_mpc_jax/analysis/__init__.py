"""Analysis modes over trained agents (the `diagnose` and `evaluate` commands' studies): the objective
against Monte Carlo returns, decision traces and departures, the reward head's calibration, noise
sweeps and planner-setting comparisons. Nothing in the library's core imports them."""
