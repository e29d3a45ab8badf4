r"""Trains LD-MPC: one run, several training seeds, or the ablation ladder.

  python -m experiments.train --config=door_open.py:cpu --workdir=runs/door_open_cpu
  python -m experiments.train --config=door_open_online.py:cpu --workdir=runs/online  # online
  python -m experiments.train --config=door_open_online.py:cpu --workdir=runs/three \
      --config.train.num_seeds=3          # three training seeds in one process (vmapped)
  python -m experiments.train --config=door_open.py:cpu --seeds=0,1,2 --workdir=runs/sweep
                                          # one process per seed, then evaluated and pooled
  python -m experiments.train ablations --workdir=runs/ablations     # the ablation ladder

A bare config name resolves to the package's configs (ld_mpc_jax/configs/); `:preset` selects a
preset; any field is set with --config.field=value, e.g. --config.task=push-v3. Modes: (none)
one run; --seeds=... a seed sweep; `ablations`. `--help` lists the chosen mode's flags.
"""

from ld_mpc_jax.cli import dispatch

MODES = {'ablations': 'ablations'}  # mode word -> module of ld_mpc_jax.cli
DEFAULT = 'train'
BY_FLAG = {'--seeds': 'sweep'}  # a flag that selects a mode by itself

if __name__ == '__main__':
  dispatch(__doc__, MODES, DEFAULT, BY_FLAG)
