"""ld_mpc_jax.data.sources: the registry of data sources, their config checks, and the dataset a
config trains on (TD-MPC2 chunks read by a stand-in torch; scripted collection stubbed)."""

import numpy as np
import pytest

from ld_mpc_jax.configs import door_open, mt10
from ld_mpc_jax import envs
from ld_mpc_jax.runs.checks import validate_config
from ld_mpc_jax.data import sources
from ld_mpc_jax.data.dataset import Dataset, DatasetError
from tests.tdmpc2_chunks import fake_torch, write_mt80_chunk  # pylint: disable=unused-import


def test_data_sources_are_a_registry_with_one_line_errors():
  assert sources.SOURCES.names() == (envs.SUITE.name, 'tdmpc2')
  assert sources.SCRIPTED == envs.SUITE.name
  c = door_open.get_config('smoke')
  c.data.source = 'nosuch'
  with pytest.raises(ValueError, match=r"^config.data.source must be one of 'metaworld', "
                                       r"'tdmpc2', got 'nosuch'$"):
    sources.DataSpec.from_config(c).check()
  c.data.source = 'tdmpc2'
  with pytest.raises(ValueError, match='needs config.data.path'):
    sources.DataSpec.from_config(c).check()


def test_tdmpc2_source_config_errors(fake_torch, tmp_path, smoke_config):
  c = smoke_config
  c.data.source = 'd4rl'
  with pytest.raises(ValueError, match="config.data.source must be one of 'metaworld', 'tdmpc2', "
                                       "got 'd4rl'"):
    validate_config(c)
  c.data.source = 'tdmpc2'
  with pytest.raises(ValueError, match='needs config.data.path'):
    validate_config(c)
  obs = write_mt80_chunk(tmp_path / 'chunk_0.pt', ['mw-door-open', 'mw-reach', 'mw-door-open'])
  write_mt80_chunk(tmp_path / 'chunk_1.pt', ['mw-door-open'], seed=1)
  c.data.path = str(tmp_path / 'chunk_*.pt')  # A glob pattern: both chunks.
  validate_config(c)
  ds = sources.load_dataset(sources.DataSpec.from_config(c))
  assert ds.num_episodes == 3 and (ds.obs_dim, ds.act_dim) == (39, 4)
  np.testing.assert_array_equal(ds.episode(1)['obs'], obs[2])
  c.task = 'drawer-open-v3'  # In TD-MPC2's list, not in these files.
  with pytest.raises(DatasetError, match=r"config.task='drawer-open-v3' \(TD-MPC2 "
                     r"'mw-drawer-open'\): No episodes"):
    sources.load_dataset(sources.DataSpec.from_config(c))
  c.task, c.obs_dim = 'door-open-v3', 40
  with pytest.raises(DatasetError, match=r'sizes \(39, 4\), but config.obs_dim/action_dim are '
                     r'\(40, 4\)'):
    sources.load_dataset(sources.DataSpec.from_config(c))
  c.obs_dim, c.data.path = 39, str(tmp_path / 'none_*.pt')
  with pytest.raises(DatasetError, match='No TD-MPC2 chunk files'):
    sources.load_dataset(sources.DataSpec.from_config(c))


def test_multitask_config_joins_every_tasks_scripted_data(monkeypatch):
  """collection.get_or_collect stubbed: task k's episodes hold the value k, one episode of k + 2
  decisions per task."""
  names = list(mt10.MT10_TASKS[:3])
  seen = []

  def fake(task, preset, episodes, seed, data_dir, action_repeat, max_episode_steps, progress):
    seen.append(task)
    k, n = names.index(task), names.index(task) + 2
    return Dataset.from_episodes([dict(obs=np.full((n + 1, 39), k, np.float32),
                                       action=np.zeros((n, 4), np.float32),
                                       reward=np.zeros(n, np.float32))],
                                 metadata=dict(task=task))

  monkeypatch.setattr(sources.collection, 'get_or_collect', fake)
  c = mt10.get_config('smoke')
  c.tasks = tuple(names)
  ds = sources.load_dataset(sources.DataSpec.from_config(c), progress=False)
  assert seen == names
  np.testing.assert_array_equal(ds.task_ids, [0, 1, 2])
  np.testing.assert_array_equal(ds.episode_lengths, [2, 3, 4])
  assert all(np.all(ds.episode(k)['obs'] == k) for k in range(3))
  assert ds.metadata['tasks'] == names
  assert [m['task'] for m in ds.metadata['per_task']] == names
