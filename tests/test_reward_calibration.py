"""The reward head's calibration (ld_mpc_jax.analysis.reward_calibration): AUC and the table against
hand counts, and the predicted reward of a transition read from the window that starts at it."""

import numpy as np

from ld_mpc_jax.analysis import reward_calibration as rc
from ld_mpc_jax.model.settings import ModelSettings


def test_auc_and_reliability_hand_counted():
  predicted = np.array([0.95, 0.2, 0.05, 0.6, 0.05])
  success = np.array([1, 1, 0, 0, 0], np.float32)
  # Positives 0.95 and 0.2 against negatives 0.05, 0.6, 0.05: 3 + 2 of 6 pairs won.
  assert rc.auc(predicted, success) == 5 / 6
  assert rc.auc([0.5, 0.5], [1, 0]) == 0.5  # A tie counts half.
  assert np.isnan(rc.auc([0.5], [1]))
  s = rc.calibration(predicted, success)
  assert (s['transitions'], s['successes']) == (5, 2)
  np.testing.assert_allclose([s['mean_on_successes'], s['mean_on_others']], [0.575, 0.7 / 3])
  rows = {r['bin']: (r['transitions'], r['successes']) for r in s['reliability']}
  assert rows['[0, 0.1)'] == (2, 0) and rows['[0.1, 0.3)'] == (1, 1)
  assert rows['[0.5, 0.7)'] == (1, 0) and rows['[0.9, inf)'] == (1, 1)
  assert '| [0.9, inf) | 1 | 1 | 1.000 |' in rc.markdown(s)


def test_a_transitions_prediction_sees_only_its_own_window_start(smoke_config, smoke_params):
  """The first position of the causal objective: changing later transitions of the episode
  leaves an earlier transition's predicted reward as it was."""
  rng = np.random.default_rng(0)
  episode = dict(obs=rng.normal(size=(6, 39)).astype(np.float32),
                 action=rng.uniform(-1, 1, (6, 4)).astype(np.float32))
  first = rc.predicted_rewards(ModelSettings.from_config(smoke_config), smoke_params, episode)
  assert first.shape == (6,) and np.all(np.isfinite(first))
  changed = dict(obs=episode['obs'].copy(), action=episode['action'].copy())
  changed['obs'][4:] += 1.0
  changed['action'][4:] *= -1
  second = rc.predicted_rewards(ModelSettings.from_config(smoke_config), smoke_params, changed)
  np.testing.assert_allclose(first[:4], second[:4], rtol=1e-5, atol=1e-6)
  assert not np.allclose(first[4:], second[4:])
