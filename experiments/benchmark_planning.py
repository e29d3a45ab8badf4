"""Latency, FLOPs and bound ratio of `plan()`; `evaluation`: evaluation throughput.

  python -m experiments.benchmark_planning                     # docs/benchmark.md
  python -m experiments.benchmark_planning evaluation --workdir=DIR --repeats=3

Modes: (none) plan(); `evaluation`. `--help` lists the chosen mode's flags.
"""

from ld_mpc_jax.cli import dispatch

MODES = {'evaluation': 'benchmark_evaluation'}  # mode word -> module of ld_mpc_jax.cli
DEFAULT = 'benchmark_planning'
BY_FLAG = {}  # a flag that selects a mode by itself

if __name__ == '__main__':
  dispatch(__doc__, MODES, DEFAULT, BY_FLAG)
