"""Collects scripted Meta-World episodes into a dataset file.

  python -m experiments.collect --task=door-open-v3 --preset=mixed --out=data/door.npz
  python -m experiments.collect tasks --config=mt10.py:cpu     # every task of a config, cached

Modes: (none) one task; `tasks`. `--help` lists the chosen mode's flags.
"""

from ld_mpc_jax.cli import dispatch

MODES = {'tasks': 'collect_tasks'}  # mode word -> module of ld_mpc_jax.cli
DEFAULT = 'collect'
BY_FLAG = {}  # a flag that selects a mode by itself

if __name__ == '__main__':
  dispatch(__doc__, MODES, DEFAULT, BY_FLAG)
