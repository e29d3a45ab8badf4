"""The reward head's calibration on held-out successes (ld_mpc_jax.analysis.reward_calibration).

  python -m experiments.diagnose reward --workdir=runs/sparse/seed0 --episodes=50 --out=cal.json

A policy of the checkpoint (--mode, the actor prior by default) runs held-out episodes; every
transition's predicted reward is compared with whether it solved the task: means, AUC and a
reliability table, printed and written to --out (JSON, .md beside it). Several --workdir pool.
"""

import json
import os

from absl import flags, logging
import numpy as np

from ld_mpc_jax.cli import errors as cli

_WORKDIR = flags.DEFINE_multi_string('workdir', None, 'A run directory (repeat to pool seeds).')
_MODE = flags.DEFINE_enum('mode', 'actor', ['actor', 'plan', 'proposal'], 'Who acts.')
_EPISODES = flags.DEFINE_integer('episodes', 50, 'Held-out episodes per run.')
_SEED = flags.DEFINE_integer('seed', 0, 'Evaluation seed (the episodes).')
_OUT = flags.DEFINE_string('out', None, 'JSON output (optional; .md beside it).')
flags.mark_flags_as_required(['workdir'])


def main(argv):
  del argv
  logging.set_verbosity(logging.WARNING)  # Keep orbax's per-restore INFO lines out.
  from ld_mpc_jax.analysis import reward_calibration as rc  # pylint: disable=g-import-not-at-top
  from ld_mpc_jax.runs import checks as run_checks  # pylint: disable=g-import-not-at-top
  from ld_mpc_jax.eval.spec import EvalSpec  # pylint: disable=g-import-not-at-top
  predicted, success = [], []
  for workdir in _WORKDIR.value:
    with cli.one_line_errors():
      config, params, step = run_checks.load_for_evaluation(workdir)
      spec = EvalSpec.from_config(config)
    for episode in rc.record_episodes(spec, params, _MODE.value, _EPISODES.value, _SEED.value):
      predicted.append(rc.predicted_rewards(spec.act.model, params, episode))
      success.append(episode['success'])
    print(f'{workdir}: update step {step}, {_EPISODES.value} held-out episodes', flush=True)
  summary = rc.calibration(np.concatenate(predicted), np.concatenate(success))
  table = rc.markdown(summary)
  print(table)
  if _OUT.value:
    os.makedirs(os.path.dirname(os.path.abspath(_OUT.value)), exist_ok=True)
    with open(_OUT.value, 'w') as f:
      json.dump(dict(summary, workdirs=_WORKDIR.value, mode=_MODE.value, seed=_SEED.value,
                     episodes=_EPISODES.value), f, indent=1)
    with open(os.path.splitext(_OUT.value)[0] + '.md', 'w') as f:
      f.write(table)
