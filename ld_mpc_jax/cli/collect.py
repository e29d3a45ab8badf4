r"""Collects a scripted-policy dataset and measures the scripted policy.

  python -m experiments.collect --task=door-open-v3 --episodes=200 \
      --preset=mixed --out=runs/data/door-open-v3_mixed.npz \
      --protocol_episodes=50

Writes the dataset (atomic .npz, see docs/data.md; an existing --out is kept unless
--overwrite, and checked before collecting), prints its summary and,
with --protocol_episodes > 0, the scripted policy's success under the
evaluation protocol at the preset's noise levels (episode i of the evaluation
uses the level the preset assigns to its i-th episode).
"""

import json
import sys

from absl import app
from absl import flags
import numpy as np

from ld_mpc_jax.cli import errors as cli
from ld_mpc_jax import envs
from ld_mpc_jax.eval import evaluation
from ld_mpc_jax.data import collection as collect_lib
from ld_mpc_jax.data import dataset as dataset_lib

_TASK = flags.DEFINE_string('task', 'door-open-v3', 'Meta-World v3 task.')
_EPISODES = flags.DEFINE_integer('episodes', 200, 'Episodes to collect.')
_PRESET = flags.DEFINE_enum('preset', 'mixed', list(collect_lib.PRESETS),
                            'Noise preset.')
_SEED = flags.DEFINE_integer('seed', 0, 'Environment / collection seed.')
_ACTION_REPEAT = flags.DEFINE_integer('action_repeat', 2, 'Action repeat.')
_OUT = flags.DEFINE_string('out', None, 'Output .npz path.', required=True)
_OVERWRITE = flags.DEFINE_bool('overwrite', False, 'Replace an existing --out.')
_PROTOCOL_EPISODES = flags.DEFINE_integer(
    'protocol_episodes', 0, 'If > 0, also evaluate the noisy scripted policy '
    'under the protocol for this many episodes.')


def scripted_under_protocol(task, preset, episodes, seed, action_repeat):
  """Success of the scripted policy at `preset`'s noise under the protocol."""
  spec = collect_lib.PRESETS[preset]
  levels = collect_lib.level_assignment(preset, episodes, seed)
  policies = [evaluation.scripted_policy_with_noise(
      task, lvl['noise_std'], lvl['random_prob'], seed=seed + 1 + j)
              for j, lvl in enumerate(spec)]
  state = {'episode': -1}

  def reset():
    state['episode'] += 1

  def policy(obs):
    return policies[levels[state['episode']]](obs)

  return evaluation.evaluate(policy, task, num_episodes=episodes, seed=seed,
                             action_repeat=action_repeat, reset=reset)


def main(argv):
  del argv
  with cli.one_line_errors():
    envs.check_task(_TASK.value)
    for name in ('episodes', 'action_repeat'):
      if flags.FLAGS[name].value < 1:
        raise ValueError(f'--{name} must be >= 1, got {flags.FLAGS[name].value}')
    if _PROTOCOL_EPISODES.value < 0:
      raise ValueError(f'--protocol_episodes must be >= 0, got {_PROTOCOL_EPISODES.value}')
    cli.check_new_output(_OUT.value, _OVERWRITE.value)  # Before collecting: kept, or unwritable.
  ds = collect_lib.collect(_TASK.value, _PRESET.value, _EPISODES.value,
                           seed=_SEED.value,
                           action_repeat=_ACTION_REPEAT.value)
  try:
    dataset_lib.save(ds, _OUT.value)  # Atomic: a failed write leaves no partial file.
  except OSError as err:  # A fault of the machine (a full disk): one line, exit code 1.
    print(f'error: could not write {_OUT.value}: {err.strerror or err}', file=sys.stderr)
    sys.exit(1)
  report = dict(out=_OUT.value, preset=_PRESET.value,
                collection_seconds=ds.metadata['collection_seconds'],
                **collect_lib.summary(ds))
  report['dataset_success_per_level'] = collect_lib.success_per_level(ds)
  if _PROTOCOL_EPISODES.value > 0:
    res = scripted_under_protocol(_TASK.value, _PRESET.value,
                                  _PROTOCOL_EPISODES.value, _SEED.value,
                                  _ACTION_REPEAT.value)
    report['scripted_protocol'] = {
        k: res[k] for k in ('success_rate', 'success_ci95', 'mean_return',
                            'mean_length', 'num_episodes')}
  print(json.dumps(report, indent=1, default=lambda x: np.asarray(x).tolist()))
