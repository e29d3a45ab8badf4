"""ld_mpc_jax.data.demos and the demonstration buffer: sparse reward, the annealed share of every
batch, the files they come from, and a smoke online run that pretrains and acts on them."""

import csv

import jax.numpy as jnp
import numpy as np
import pytest

from ld_mpc_jax.configs import door_open_online
from ld_mpc_jax import data
from ld_mpc_jax.runs import train
from ld_mpc_jax.data import demos
from ld_mpc_jax.data.online_buffer import Buffer
from ld_mpc_jax.model.settings import ModelSettings
from ld_mpc_jax.online.settings import OnlineSettings
from ld_mpc_jax.online import learner as online_learner

DEMO_OBS = 5.0  # Observations of the fake demonstrations: every window from them is all 5.0.


def _episode(length, value, success_from=None):
  success = np.zeros(length, bool)
  if success_from is not None:
    success[success_from:] = True
  return dict(obs=np.full((length + 1, 39), value, np.float32),
              action=np.zeros((length, 4), np.float32),
              reward=np.linspace(0.0, 9.0, length).astype(np.float32), success=success)


def test_sparse_reward_is_one_exactly_on_solved_steps():
  ep = _episode(12, 0.0, success_from=7)
  ep['success'][9] = False  # Solved, then not: the reward follows the flag, step by step.
  (out,) = demos.with_reward([ep], 'sparse')
  np.testing.assert_array_equal(out['reward'], ep['success'].astype(np.float32))
  assert out['reward'].sum() == 4.0
  (dense,) = demos.with_reward([ep], 'dense')
  np.testing.assert_array_equal(dense['reward'], ep['reward'])


def test_demo_share_is_linear_from_start_to_end_and_zero_without_demos():
  config = door_open_online.get_config('smoke')
  o = config.online
  o.env_steps, o.demos, o.demo_share_start, o.demo_share_end = 1000, 5, 0.5, 0.25
  assert [OnlineSettings.from_config(config).demo_share(s) for s in (0, 500, 1000, 5000)] == [0.5, 0.375, 0.25, 0.25]
  o.demos = 0
  assert OnlineSettings.from_config(config).demo_share(0) == 0.0


def test_schedule_steps_moves_where_the_demo_share_ends():
  """A run continued from 1000 to 2000 steps keeps its schedule with online.schedule_steps."""
  config = door_open_online.get_config('smoke')
  o = config.online
  o.env_steps, o.demos, o.demo_share_start, o.demo_share_end = 2000, 5, 0.5, 0.25
  assert OnlineSettings.from_config(config).demo_share(1000) == 0.375
  o.schedule_steps = 1000
  assert [OnlineSettings.from_config(config).demo_share(s) for s in (500, 1000, 2000)] == [0.375, 0.25, 0.25]


@pytest.mark.parametrize('share', [0.5, 0.25, 0.0])
def test_every_batch_of_a_call_holds_its_share_of_demo_windows(share):
  buffer = Buffer(seq_len=4, offline=None, seed=0,
                  demos=[_episode(30, DEMO_OBS, 20), _episode(30, DEMO_OBS, 25)])
  # Nothing but demonstrations yet: every window comes from them, whatever the share.
  only = buffer.sample(16, groups=2, demo_share=share)
  assert only['obs'].shape == (32, 4, 39) and np.all(only['obs'] == DEMO_OBS)
  buffer.add([_episode(30, 0.0), _episode(40, 0.0)])
  windows = buffer.sample(16, groups=3, demo_share=share)
  assert windows['obs'].shape == (48, 4, 39)
  from_demos = np.all(windows['obs'] == DEMO_OBS, axis=(1, 2)).reshape(3, 16).sum(axis=1)
  np.testing.assert_array_equal(from_demos, [demos.demo_rows(16, share)] * 3)


def test_load_demos_keeps_the_first_successful_episodes(tmp_path):
  path = str(tmp_path / 'demos.npz')
  episodes = [_episode(20, 1.0), _episode(20, 2.0, 5), _episode(20, 3.0), _episode(20, 4.0, 9)]
  data.save(data.Dataset.from_episodes(episodes), path)
  got = demos.load_demos(path, 2)
  assert [float(ep['obs'][0, 0]) for ep in got] == [2.0, 4.0]
  with pytest.raises(ValueError, match='holds 2 successful episodes'):
    demos.load_demos(path, 3)


def test_a_run_with_demos_pretrains_on_them_and_plans_from_the_first_wave(tmp_path, monkeypatch):
  path = str(tmp_path / 'demos.npz')
  data.save(data.Dataset.from_episodes([_episode(10, DEMO_OBS, 6), _episode(10, DEMO_OBS, 4)]),
            path)
  config = door_open_online.get_config('smoke')
  o = config.online
  o.demos, o.demo_path, o.demo_pretrain_updates, o.reward = 2, path, 3, 'sparse'
  o.demo_seed_actor = True
  o.env_steps, o.eval_every, o.update_ratio = 80, 80, 0.1  # A seed wave, then the planner.
  config.eval.splits, config.eval.baselines, config.eval.episodes = ('held_out',), (), 2
  shares = []

  def counting(learn, n, per_call):  # Records each batch's share of demo windows; no compiling.
    def update(state, batch, keys):
      obs = np.asarray(batch['obs'])[0]  # [B, T, obs_dim] of the one seed.
      from_demos = np.all(obs == DEMO_OBS, axis=(1, 2))
      np.testing.assert_array_equal(np.asarray(batch['demo'])[0], from_demos)  # The BC mask.
      shares.append(float(np.mean(from_demos)))
      return state.replace(step=state.step + 1), {'loss': jnp.ones(n, jnp.float32)}
    return update
  monkeypatch.setattr(online_learner, 'make_seeds_update', counting)
  report = train.train_and_evaluate(config, str(tmp_path / 'run'))
  assert report['demos'] == 2 and report['updates'] == 8  # 0.1 x 80 environment steps.
  # The pretraining (demos alone), then the updates during the first wave: its episodes join the
  # buffer only at its end, so these too come from the demos; then the annealed share
  # (0.5 -> 0.25 over the 80 steps) when the second wave reaches 0.1 x steps = 5, 6, 7, 8
  # updates (4 environment steps a decision: at 52, 60, 72 and 80).
  batch = config.train.batch_size
  expected = [demos.demo_rows(batch, OnlineSettings.from_config(config).demo_share(s)) / batch
              for s in (52, 60, 72, 80)]
  assert shares == [1.0] * 7 + expected and expected[0] > expected[-1] == 0.25
  # MoDem's seeding phase: the seed wave acts with the actor prior, then the planner.
  with open(tmp_path / 'run' / 'online.csv') as f:
    assert [r['acting'] for r in csv.DictReader(f)] == ['actor', 'planner']


def test_demo_bc_loss_averages_the_actor_error_over_demo_windows_only():
  from ld_mpc_jax.learn.losses import demo_bc_loss
  from ld_mpc_jax.model.models import build_networks, init_params
  import jax
  config = door_open_online.get_config('smoke')
  nets = build_networks(ModelSettings.from_config(config))
  params = init_params(config, jax.random.key(0))
  z = jax.random.normal(jax.random.key(1), (3, 2, config.model.latent_dim))
  action = jnp.zeros((3, 2, 4))
  demo = jnp.array([1.0, 0.0, 1.0])
  a_pi = np.asarray(nets.actor.apply({'params': params['actor']}, z))
  per_window = np.mean(np.sum(a_pi ** 2, axis=-1), axis=-1)
  np.testing.assert_allclose(demo_bc_loss(nets, params, z, action, demo),
                             (per_window[0] + per_window[2]) / 2, rtol=1e-5)
  assert float(demo_bc_loss(nets, params, z, action, jnp.zeros(3))) == 0.0


def test_a_sparse_fine_tuning_run_sees_its_offline_data_with_the_sparse_reward():
  ds = data.Dataset.from_episodes([_episode(12, 0.0, success_from=7), _episode(5, 1.0)])
  sparse = demos.sparse_dataset(ds)
  np.testing.assert_array_equal(sparse.rewards, ds.successes.astype(np.float32))
  assert sparse.rewards.sum() == 5.0 and ds.rewards.sum() > 5.0  # The dense copy is untouched.
  np.testing.assert_array_equal(sparse.observations, ds.observations)
