"""Tests for the replay buffer: boundaries, alignment, uniformity, errors."""

import numpy as np
import pytest

from ld_mpc_jax.data import dataset as dataset_lib
from ld_mpc_jax.data.replay import ReplayBuffer

LENGTHS = (6, 2, 9, 3, 4)  # Transitions per episode.


def _labelled():
  """obs = (episode, step); action/reward encode the step they follow."""
  eps = []
  for e, n in enumerate(LENGTHS):
    steps = np.arange(n + 1)
    eps.append(dict(
        obs=np.stack([np.full(n + 1, e), steps], -1),
        action=np.stack([np.full(n, e), steps[:-1]], -1),
        reward=1000.0 * e + steps[:-1]))
  return dataset_lib.Dataset.from_episodes(eps)


def test_samples_never_cross_episodes_and_are_aligned():
  buf = ReplayBuffer(_labelled(), seq_len=4, seed=0)
  batch = buf.sample(4096)
  assert batch['obs'].shape == (4096, 4, 2)
  assert batch['action'].shape == (4096, 3, 2)
  assert batch['reward'].shape == (4096, 3)
  assert all(v.dtype == np.float32 for v in batch.values())
  ep, step = batch['obs'][..., 0], batch['obs'][..., 1]
  assert np.all(ep == ep[:, :1])  # One episode per sample.
  assert np.all(np.diff(step, axis=1) == 1)  # Consecutive steps.
  lengths = np.array(LENGTHS)[ep[:, 0].astype(int)]
  assert np.all(step[:, -1] <= lengths)  # Last obs still in the episode.
  # action[t] is taken at obs[t]; reward[t] follows action[t].
  np.testing.assert_array_equal(batch['action'], batch['obs'][:, :-1])
  np.testing.assert_array_equal(
      batch['reward'], 1000 * ep[:, :-1] + step[:, :-1])


def test_every_valid_window_is_sampled_uniformly():
  buf = ReplayBuffer(_labelled(), seq_len=4, seed=1)
  # Episode of n transitions offers n - 2 windows of 3 transitions.
  expected = {(e, s) for e, n in enumerate(LENGTHS) for s in range(n - 2)}
  assert buf.num_windows == len(expected) == 14
  obs = buf.sample(28000)['obs']
  got = [tuple(x) for x in obs[:, 0].astype(int)]
  keys, counts = np.unique(np.array(got), axis=0, return_counts=True)
  assert {tuple(k) for k in keys} == expected
  assert counts.min() > 0.8 * 2000 and counts.max() < 1.2 * 2000


def test_reproducible_from_seed():
  a = ReplayBuffer(_labelled(), 3, seed=5).sample(64)
  b = ReplayBuffer(_labelled(), 3, seed=5).sample(64)
  c = ReplayBuffer(_labelled(), 3, seed=6).sample(64)
  np.testing.assert_array_equal(a['obs'], b['obs'])
  assert not np.array_equal(a['obs'], c['obs'])


def test_skip_advances_as_sampling_would():
  """A resumed run skips the batches of the steps before its checkpoint and then draws what
  the uninterrupted run draws."""
  whole, resumed = ReplayBuffer(_labelled(), 3, seed=5), ReplayBuffer(_labelled(), 3, seed=5)
  for _ in range(7):
    whole.sample(5)
  resumed.skip(7, 5)
  for _ in range(3):
    np.testing.assert_array_equal(resumed.sample(5)['obs'], whole.sample(5)['obs'])
  one_call = ReplayBuffer(_labelled(), 3, seed=5)
  one_call.skip(1, 35)  # Not the same draws: skip keeps the calls' sizes.
  assert not np.array_equal(one_call.sample(5)['obs'], ReplayBuffer(_labelled(), 3, seed=5)
                            .sample(5)['obs'])


def test_longest_window_uses_whole_episode():
  buf = ReplayBuffer(_labelled(), seq_len=10, seed=0)  # Only episode 2 fits.
  obs = buf.sample(16)['obs']
  assert buf.num_windows == 1
  assert np.all(obs[..., 0] == 2)
  np.testing.assert_array_equal(obs[0, :, 1], np.arange(10))


def test_errors():
  ds = _labelled()
  with pytest.raises(ValueError, match='No episode is long enough'):
    ReplayBuffer(ds, seq_len=11, seed=0)
  with pytest.raises(ValueError, match='seq_len'):
    ReplayBuffer(ds, seq_len=1, seed=0)
  with pytest.raises(ValueError, match='seq_len'):
    ReplayBuffer(ds, seq_len=2.5, seed=0)
  buf = ReplayBuffer(ds, seq_len=2, seed=0)
  with pytest.raises(ValueError, match='batch_size'):
    buf.sample(0)


def test_online_buffer_keeps_planned_sequences_and_windows_carry_their_first_rows(tmp_path):
  """Buffer(plan_shape=(H, A)): an episode's plans [L, H, A] survive a save and a load, each
  window carries its first row's plan (has_plan 1) or zeros (has_plan 0: an episode without
  plans), and the windows drawn are the ones a buffer without plans draws."""
  from ld_mpc_jax.data.online_buffer import Buffer  # pylint: disable=g-import-not-at-top
  rng = np.random.default_rng(0)
  n, h = 5, 2

  def episode(e, planned):
    ep = dict(obs=np.stack([np.full(n + 1, e), np.arange(n + 1)], -1).astype(np.float32),
              action=rng.uniform(-1, 1, (n, 2)).astype(np.float32),
              reward=np.zeros(n, np.float32), success=np.zeros(n, bool))
    if planned:  # plan[t] = t + 10 e everywhere: the row is readable from the plan.
      ep['plan'] = np.broadcast_to((np.arange(n) + 10 * e)[:, None, None], (n, h, 2)).astype(
          np.float32)
    return ep
  episodes = [episode(0, True), episode(1, False), episode(2, True)]
  buffer, plain = Buffer(4, None, seed=3, plan_shape=(h, 2)), Buffer(4, None, seed=3)
  buffer.add(episodes)
  plain.add([{k: v for k, v in ep.items() if k != 'plan'} for ep in episodes])
  buffer.save(str(tmp_path / 'b.npz'), {'env_steps': 15})
  loaded = Buffer(4, None, seed=3, plan_shape=(h, 2))
  assert loaded.load(str(tmp_path / 'b.npz')) == {'env_steps': 15}
  assert ['plan' in ep for ep in loaded.episodes] == [True, False, True]
  np.testing.assert_array_equal(loaded.episodes[2]['plan'], episodes[2]['plan'])
  batch, same = loaded.sample(64), plain.sample(64)
  np.testing.assert_array_equal(batch['obs'], same['obs'])
  e, t = batch['obs'][:, 0, 0].astype(int), batch['obs'][:, 0, 1]
  np.testing.assert_array_equal(batch['has_plan'], (e != 1).astype(np.float32))
  expected = np.where(e != 1, t + 10 * e, 0.0)
  np.testing.assert_array_equal(batch['plan'], np.broadcast_to(expected[:, None, None],
                                                               (64, h, 2)))
