r"""What happened inside chosen held-out episodes: the reward terms of the environment per step,
for the actor prior and planner variants, on the same episodes as compare_selection.

  python -m experiments.diagnose trace --workdir=runs/obj2/door_open_weak/seed0 \\
      --episodes=11,29,39 [--variant=safe2x:plan.safe_selection=True,...] [--seed=0] \\
      [--out=runs/trace.json]

Each policy runs the given episodes (indices into the 50-episode held-out list of evaluation
seed --seed; --num_episodes sets that list's length) in lockstep, and each episode's row gives:
success and the decision of first success, decisions run, the return, the largest per-decision
reward, the mean reward of the last 50 decisions, and for each scalar term of the
environment's `info` (Meta-World's near_object, grasp_reward, in_place_reward, obj_to_target,
unscaled_reward, ...) its value at the last decision and its largest value. A planner that
loses an episode its actor prior solves either never got as far (the terms' largest values
lower) or got there and fell back (largest high, last low).
"""

import json
import os

from absl import app, flags, logging

from ld_mpc_jax.cli import errors as cli
from ld_mpc_jax.configs import overrides

_WORKDIR = flags.DEFINE_string('workdir', None, 'Training run directory (one checkpoint).')
_EPISODES = flags.DEFINE_list('episodes', None, 'Held-out episode indices to trace.')
_VARIANTS = flags.DEFINE_multi_string('variant', [], 'NAME:field=value,... planner settings '
                                      '(as compare_selection); the actor prior always runs.')
_PLAN = flags.DEFINE_bool('plan', True, 'Also trace the planner as trained.')
_SEED = flags.DEFINE_integer('seed', 0, 'Evaluation seed (the episodes).')
_NUM_EPISODES = flags.DEFINE_integer('num_episodes', 50, 'Length of the held-out list.')
_OUT = flags.DEFINE_string('out', None, 'JSON output of the rows (optional).')
flags.mark_flags_as_required(['workdir', 'episodes'])


def main(argv):
  del argv
  logging.set_verbosity(logging.WARNING)
  from ld_mpc_jax.runs import checks as run_checks
  from ld_mpc_jax.analysis import diagnostics
  from ld_mpc_jax.eval.spec import EvalSpec
  with cli.one_line_errors():
    indices = cli.int_list('--episodes', _EPISODES.value)
    if not indices or min(indices) < 0 or max(indices) >= _NUM_EPISODES.value:
      raise ValueError(f'--episodes must be indices in [0, {_NUM_EPISODES.value}), '
                       f'got {_EPISODES.value}')
    if not os.path.isdir(_WORKDIR.value):
      raise FileNotFoundError(f'no run directory {_WORKDIR.value}')
    config, params, _ = run_checks.load_for_evaluation(_WORKDIR.value)
    runs = [('actor', 'actor', config)] + ([('plan', 'plan', config)] if _PLAN.value else [])
    for name, items in (overrides.parse_variant(v) for v in _VARIANTS.value):
      runs.append((f'plan[{name}]', 'plan', overrides.with_overrides(config, items)))
    runs = [(policy, mode, EvalSpec.from_config(cfg)) for policy, mode, cfg in runs]
  rows = []
  for policy, mode, spec in runs:
    rows.extend(diagnostics.trace_episodes(spec, params, mode, indices, _SEED.value,
                                           _NUM_EPISODES.value, policy))
  print(diagnostics.trace_markdown(rows), end='')
  if _OUT.value:
    with open(_OUT.value, 'w') as f:
      json.dump(dict(workdir=_WORKDIR.value, seed=_SEED.value, rows=rows), f, indent=1)
    print(f'wrote {_OUT.value}')
