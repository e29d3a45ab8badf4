r"""What the planner's departures from its actor prior gain, and where the gain comes from.

  python -m experiments.diagnose departures --workdir=runs/obj/door_open_weak/seed0 \\
      --episodes=11,29,39,0,1 [--variant=safe2x:plan.safe_selection=True,...] [--seed=0] \\
      [--draws=8] [--out=runs/gains.json]
  python -m experiments.diagnose departures --summarize=runs/gains.json   # the table again

The planner (as trained, or one --variant as compare_selection takes it) runs the given
held-out episodes (indices into the 50-episode list of evaluation seed --seed, with the
evaluation's own key schedule, so it makes the decisions compare_selection's evaluation made).
At every decision that departs from the actor prior's own sequence, the executed sequence and
the actor prior acting along its own rollout are rolled out again --draws times, and the gain in
J is split into its two parts: the discounted rewards over the horizon and gamma^H times the
value members' mean at the horizon's end. Each episode's row: success, the share of decisions
that departed, the mean reward gain and value gain of its departures, the share of departures
led by the value (value gain above reward gain) and the median gain relative to the actor
prior's J, and the share of departures whose gain is negative on the fresh rollouts. The JSON
keeps every decision with the environment's reward terms (Meta-World's near_object,
in_place_reward, ...), to line the departures up with what happened.
"""

import json
import os

from absl import app, flags, logging

from ld_mpc_jax.cli import errors as cli
from ld_mpc_jax.configs import overrides

_WORKDIR = flags.DEFINE_string('workdir', None, 'Training run directory (one checkpoint).')
_EPISODES = flags.DEFINE_list('episodes', None, 'Held-out episode indices.')
_VARIANT = flags.DEFINE_string('variant', None, 'NAME:field=value,... planner settings '
                               '(as compare_selection); default: the planner as trained.')
_SEED = flags.DEFINE_integer('seed', 0, 'Evaluation seed (the episodes).')
_NUM_EPISODES = flags.DEFINE_integer('num_episodes', 50, 'Length of the held-out list.')
_DRAWS = flags.DEFINE_integer('draws', 8, 'Fresh dynamics rollouts per departure.')
_OUT = flags.DEFINE_string('out', None, 'JSON output (optional).')
_SUMMARIZE = flags.DEFINE_string('summarize', None, 'Print the table of an --out JSON instead.')


def main(argv):
  del argv
  logging.set_verbosity(logging.WARNING)
  from ld_mpc_jax.runs import checks as run_checks
  from ld_mpc_jax.analysis import diagnostics
  from ld_mpc_jax.eval.spec import EvalSpec
  if _SUMMARIZE.value:
    with cli.one_line_errors():
      with open(_SUMMARIZE.value) as f:
        episodes = json.load(f)['episodes']
    print(diagnostics.gains_markdown([diagnostics.summarize_gains(e) for e in episodes]), end='')
    return
  with cli.one_line_errors():
    if not _WORKDIR.value or not _EPISODES.value:
      raise ValueError('give --workdir and --episodes (or --summarize=JSON)')
    indices = cli.int_list('--episodes', _EPISODES.value)
    if not indices or min(indices) < 0 or max(indices) >= _NUM_EPISODES.value:
      raise ValueError(f'--episodes must be indices in [0, {_NUM_EPISODES.value}), '
                       f'got {_EPISODES.value}')
    if _DRAWS.value < 1:
      raise ValueError(f'--draws must be >= 1, got {_DRAWS.value}')
    if not os.path.isdir(_WORKDIR.value):
      raise FileNotFoundError(f'no run directory {_WORKDIR.value}')
    config, params, _ = run_checks.load_for_evaluation(_WORKDIR.value)
    if _VARIANT.value:
      _, items = overrides.parse_variant(_VARIANT.value)
      config = overrides.with_overrides(config, items)
    spec = EvalSpec.from_config(config)
  episodes = diagnostics.departure_gains(spec, params, indices, _SEED.value,
                                         _NUM_EPISODES.value, _DRAWS.value)
  summaries = [diagnostics.summarize_gains(e) for e in episodes]
  print(diagnostics.gains_markdown(summaries), end='')
  if _OUT.value:
    with open(_OUT.value, 'w') as f:
      json.dump(dict(workdir=_WORKDIR.value, seed=_SEED.value, variant=_VARIANT.value,
                     summaries=summaries, episodes=episodes), f, indent=1)
    print(f'wrote {_OUT.value}')
