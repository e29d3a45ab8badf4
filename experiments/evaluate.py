"""Evaluates trained runs on held-out goals, every policy on the same episodes.

  python -m experiments.evaluate --workdir=DIR --seeds=0,1,2      # one checkpoint, pooled seeds
  python -m experiments.evaluate --workdir=DIR --config.plan.safe_selection=True   # a setting
  python -m experiments.evaluate selection --workdir=A --workdir=B --variant=safe --out=sel.json
                                  # planner settings against the actor prior, over training seeds
  python -m experiments.evaluate mt10 --workdir=DIR --out=mt10.json  # Meta-World's MT10 protocol
  python -m experiments.evaluate bc --run=DIR --out=bc.json        # BC on the same demonstrations

Modes: (none) one checkpoint; `selection`; `mt10`; `bc`. `--help` lists the chosen mode's flags.
"""

from ld_mpc_jax.cli import dispatch

MODES = {'selection': 'compare_selection', 'mt10': 'evaluate_mt10', 'bc': 'bc_baseline'}  # mode word -> module of ld_mpc_jax.cli
DEFAULT = 'evaluate'
BY_FLAG = {}  # a flag that selects a mode by itself

if __name__ == '__main__':
  dispatch(__doc__, MODES, DEFAULT, BY_FLAG)
