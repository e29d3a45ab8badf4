"""ld_mpc_jax.model.objective: the members of J combined (mean - pessimism x std) and the value head's
loss, against hand-computed values."""

import jax.numpy as jnp
import numpy as np

from ld_mpc_jax.model import objective


def test_combine_is_mean_less_pessimism_times_std():
  ens = jnp.array([[1.0, 2.0], [3.0, 2.0]])  # 2 members x 2 states
  np.testing.assert_allclose(objective.combine(ens, 0.5), [2.0 - 0.5, 2.0], rtol=1e-6)
  np.testing.assert_allclose(objective.combine(ens, -1.0), [3.0, 2.0], rtol=1e-6)  # Optimism.
  # One member: its own scores whatever the pessimism.
  np.testing.assert_allclose(objective.combine(jnp.array([[4.0, -1.0]]), 3.0), [4.0, -1.0])


def test_as_members_gives_scores_a_member_axis():
  assert objective.as_members(jnp.zeros(5)).shape == (1, 5)
  assert objective.as_members(jnp.zeros((3, 5))).shape == (3, 5)


def test_value_head_loss_hand_computed():
  # expm1(0.25) two-hots to 0.75 on bin 2 and 0.25 on bin 3.
  probs = jnp.array([0.1, 0.1, 0.5, 0.2, 0.1])
  got = objective.value_head_loss(jnp.log(probs)[None], jnp.array([np.expm1(0.25)]), 5, -2.0,
                                  2.0)
  np.testing.assert_allclose(got, -(0.75 * np.log(0.5) + 0.25 * np.log(0.2)), rtol=1e-5)
