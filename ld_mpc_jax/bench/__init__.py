"""Benchmarking tools, apart from the model code: FLOP counts and profiles of a plan call.

Only the benchmark launchers (experiments.benchmark_planning, experiments.profile_plan) use them.
"""
