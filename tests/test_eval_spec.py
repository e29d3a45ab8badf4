"""ld_mpc_jax.eval.spec: an evaluation's settings built once from a config; its cache keys are
byte for byte those of the config (the formula the keys had when evaluations took the config)."""

import hashlib
import itertools
import json

import numpy as np
import pytest

from ld_mpc_jax.configs import door_open, door_open_online, mt10
from ld_mpc_jax.configs.overrides import with_overrides
from ld_mpc_jax.eval import evaluation_suite
from ld_mpc_jax.eval.spec import EvalSpec, GoalSource
from ld_mpc_jax.learn import checkpointing
from tests.tdmpc2_chunks import fake_torch, write_mt80_chunk  # pylint: disable=unused-import


def _config_key(config, step, mode, split, seed, num_episodes, obs_noise_std, version):
  """An evaluation's cache key computed from the config itself, as evaluation_suite did."""
  dumps = lambda v: json.dumps(v, sort_keys=True, default=str)
  without = lambda s, d: {k: v for k, v in s.items() if k not in d or dumps(v) != dumps(d[k])}
  plan, data = config.plan.to_dict(), config.data.to_dict()
  if version >= 3:
    neutral = checkpointing.legacy_defaults()
    plan, data = without(plan, neutral['plan']), without(data, neutral['data'])
  relevant = dict(version=version, step=step, mode=mode, split=split, seed=seed,
                  episodes=num_episodes, noise=obs_noise_std, task=config.task, plan=plan,
                  mppi=config.mppi.to_dict(), data=data,
                  eval={k: config.eval[k] for k in ('action_repeat', 'max_episode_steps')})
  if config.eval.key_seed >= 0:
    relevant['eval']['key_seed'] = config.eval.key_seed
  if config.eval.action_noise > 0:
    relevant['eval']['action_noise'] = float(config.eval.action_noise)
  if obs_noise_std > 0 and config.eval.obs_noise_dims != 'all':
    relevant['eval']['obs_noise_dims'] = config.eval.obs_noise_dims
  return hashlib.sha1(dumps(relevant).encode()).hexdigest()[:10]


def _task_config(config, k):
  """A copy of multi-task `config` for task index `k` alone (config.task set, config.tasks
  removed): the config whose spec a task's spec must be."""
  out = with_overrides(config, {'task': tuple(config.tasks)[k]})
  del out['tasks']
  return out


def _configs(tmp_path):
  smoke = door_open.get_config('smoke')
  yield smoke
  yield door_open.get_config()
  yield with_overrides(smoke, {'eval.key_seed': 4, 'eval.action_noise': 0.05,
                               'eval.obs_noise_dims': 'informative'})
  yield with_overrides(smoke, {'plan.safe_margin_scaling': 'none',
                               'plan.first_round': ('proposal', 'gaussian')})
  checkpointing.save_config(smoke, str(tmp_path))  # Read back: tuples as lists.
  yield checkpointing.load_config(str(tmp_path))


def test_cache_keys_are_the_configs_byte_for_byte(tmp_path):
  grid = list(itertools.product((0, 400), ('plan', 'actor'), ('held_out', 'train'), (0, 3), (50,),
                                (0.0, 0.05), (2, 3, 4)))
  for config in _configs(tmp_path):
    spec = EvalSpec.from_config(config)
    for cell in grid:
      assert evaluation_suite._cache_key(spec, *cell) == _config_key(config, *cell), cell
  config = mt10.get_config('smoke')
  for k, (name, spec) in enumerate(EvalSpec.from_config(config).tasks):
    assert spec.task == name
    for cell in grid[:8]:
      assert (evaluation_suite._cache_key(spec, *cell)
              == _config_key(_task_config(config, k), *cell))


def test_a_variant_of_the_planner_is_the_spec_of_the_changed_config():
  config = door_open.get_config('smoke')
  spec = EvalSpec.from_config(config)
  changed = {'num_candidates': 4, 'num_prior_candidates': 1}
  assert spec.with_plan(**changed) == EvalSpec.from_config(
      with_overrides(config, {f'plan.{k}': v for k, v in changed.items()}))
  assert spec == EvalSpec.from_config(config) and hash(spec) == hash(EvalSpec.from_config(config))
  with pytest.raises(ValueError):  # Checked as the config's planner settings are.
    spec.with_plan(num_candidates=1, num_prior_candidates=2)


def test_a_multi_task_spec_holds_each_tasks():
  config = mt10.get_config('smoke')
  spec = EvalSpec.from_config(config)
  assert spec.multitask and [n for n, _ in spec.tasks] == list(config.tasks)
  _, first = spec.tasks[0]
  assert first == EvalSpec.from_config(_task_config(config, 0)) and not first.multitask
  assert not EvalSpec.from_config(door_open.get_config('smoke')).multitask


def test_the_goal_source_of_each_kind_of_training_data():
  config = door_open.get_config('smoke')
  source = GoalSource.from_config(config)
  assert (source.task, source.online, source.data.source) == (config.task, '', 'metaworld')
  assert source.data.action_repeat == config.eval.action_repeat  # The data's, as collected.
  online = door_open_online.get_config('smoke')
  assert GoalSource.from_config(online).online == 'mt1'
  online.online.train_goals = 'random'
  assert GoalSource.from_config(online).online == 'random'
  online.online.init_from = '/some/run'  # Fine-tuning: the dataset's goals.
  assert GoalSource.from_config(online).online == ''
  tdmpc2 = with_overrides(config, {'data.source': 'tdmpc2', 'data.path': '/chunks'})
  source = GoalSource.from_config(tdmpc2)
  assert source.data.path == '/chunks' and source.data.source == 'tdmpc2'
  assert source == GoalSource.from_config(tdmpc2)  # A value: equal for equal configs.


def test_tdmpc2_goals_come_from_the_chunks_training_read(fake_torch, tmp_path):
  from ld_mpc_jax import data
  from ld_mpc_jax.envs import goals
  write_mt80_chunk(tmp_path / 'chunk_0.pt', ['mw-door-open', 'mw-reach', 'mw-door-open'])
  config = with_overrides(door_open.get_config('smoke'), {
      'data.source': 'tdmpc2', 'data.path': str(tmp_path / 'chunk_*.pt')})
  spec = EvalSpec.from_config(config)
  config.data.path = '/elsewhere'  # The spec's loader reads the config as it was.
  vectors, mt1_seed = evaluation_suite.dataset_goals(spec.goals)
  assert mt1_seed is None and vectors.shape == (2, 6)
  expected = goals.dataset_goal_vectors(data.load_dataset(data.DataSpec.from_config(
      with_overrides(config, {'data.path': str(tmp_path / 'chunk_*.pt')}))))
  np.testing.assert_array_equal(vectors, expected)
  assert evaluation_suite.available_splits(spec.goals, ('held_out', 'train')) == ('held_out',)
