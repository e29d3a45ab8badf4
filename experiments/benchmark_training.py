"""Time per update step; `--online_seeds`: N training seeds in one online run; `versions`: two
checkouts' update step in one process.

  python -m experiments.benchmark_training                      # docs/scaling.md
  python -m experiments.benchmark_training --online_seeds=1,3
  python -m experiments.benchmark_training versions --baseline=../other_checkout

Modes: (none) update steps; `versions`. `--help` lists the chosen mode's flags.
"""

from ld_mpc_jax.cli import dispatch

MODES = {'versions': 'compare_update_speed'}  # mode word -> module of ld_mpc_jax.cli
DEFAULT = 'benchmark_training'
BY_FLAG = {}  # a flag that selects a mode by itself

if __name__ == '__main__':
  dispatch(__doc__, MODES, DEFAULT, BY_FLAG)
