"""Looks inside a trained planner: its objective, its decisions, its cost.

  python -m experiments.diagnose --workdir=DIR          # the objective's ranking against K
  python -m experiments.diagnose trace --workdir=DIR --episodes=3,7   # decision by decision
  python -m experiments.diagnose departures --workdir=DIR --episodes=3 # what departures gain
  python -m experiments.diagnose profile --config=door_open.py:cpu      # XLA profile of plan()
  python -m experiments.diagnose reward --workdir=DIR     # the reward head on held-out successes

Modes: (none) objective; `trace`; `departures`; `profile`; `reward`. `--help` lists the chosen mode's flags.
"""

from ld_mpc_jax.cli import dispatch

MODES = {'trace': 'episode_trace', 'departures': 'departure_gains', 'profile': 'profile_plan',
         'reward': 'reward_calibration'}  # mode word -> module of ld_mpc_jax.cli
DEFAULT = 'diagnose_objective'
BY_FLAG = {}  # a flag that selects a mode by itself

if __name__ == '__main__':
  dispatch(__doc__, MODES, DEFAULT, BY_FLAG)
