"""Environment-loop policies: planner (cold and warm), actor prior, proposal alone."""

import numpy as np
import pytest

from ld_mpc_jax.agent import make_policy
from ld_mpc_jax.models import build_networks, encode


@pytest.mark.parametrize('mode', ['plan', 'actor', 'proposal'])
def test_policies_return_valid_actions(smoke_config, smoke_params, mode):
  policy, reset = make_policy(smoke_config, smoke_params, mode, seed=0)
  obs = np.linspace(-1, 1, 39)
  actions = [policy(obs) for _ in range(3)]
  reset()
  for a in actions:
    assert a.shape == (4,) and np.all(np.abs(a) <= 1.0)


def test_actor_policy_is_the_actor_prior(smoke_config, smoke_params):
  policy, _ = make_policy(smoke_config, smoke_params, 'actor')
  obs = np.linspace(-1, 1, 39).astype(np.float32)
  nets = build_networks(smoke_config)
  expected = nets.actor.apply({'params': smoke_params['actor']}, encode(smoke_params, obs))
  np.testing.assert_allclose(policy(obs), expected, rtol=1e-5, atol=1e-6)


def test_warm_started_policy_is_reproducible(smoke_config, smoke_params):
  smoke_config.plan.warm_start_steps = 1
  obs = [np.full(39, v) for v in (0.1, 0.2, 0.3)]
  runs = []
  for _ in range(2):
    policy, reset = make_policy(smoke_config, smoke_params, 'plan', seed=3)
    reset()
    runs.append([policy(o) for o in obs])
  np.testing.assert_array_equal(np.stack(runs[0]), np.stack(runs[1]))
