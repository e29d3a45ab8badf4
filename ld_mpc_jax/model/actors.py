"""The actor prior and how it is trained, one registry entry per kind (`config.critic.actor`).

  'awr'   advantage-weighted regression onto the data's actions (IQL eq. 7), on detached latents;
  'bc'    behaviour cloning of the data's actions (the encoder learns from it);
  'maxq'  a stochastic policy maximising Q with an entropy bonus (TD-MPC2, SAC), for learning
          online; 'awr' and 'bc' rank only the data's own actions (offline).

An entry carries whether its actor is `stochastic` (Actor.sample), whether it `needs_critics`
(the Q and V ensembles of ld_mpc_jax.model.critics), the value kind it requires (`value`, None for
any), and its loss term
`loss(losses, nets, params, z [B, H+2, D], action [B, H+1, A], weights [B, H+1], key) -> []`,
where `weights` are the critics' AWR weights (None without critics).
"""

import flax.linen as nn
import jax
import jax.numpy as jnp

from ld_mpc_jax.model.settings import LossSettings, ModelSettings
from ld_mpc_jax.nets import MLP
from ld_mpc_jax.ops.registry import Registry

ACTORS = Registry('actor', 'config.critic.actor')

# How the stochastic actor's raw output x becomes its log-std (config.critic.log_std_map), both
# within TD-MPC2's bounds [-10, 2]:
#   'clip'  clip(x, -10, 2): log-std 0 (std 1) at x = 0, no gradient outside the bounds;
#   'tanh'  -10 + 6 (tanh(x) + 1), TD-MPC2's math.log_std: log-std -4 (std 0.018) at x = 0, a
#           smooth gradient everywhere.
LOG_STD_MAPS = ('clip', 'tanh')
LOG_STD_MIN, LOG_STD_MAX = -10.0, 2.0


def check_log_std_map(kind: str) -> None:
  """One-line ValueError unless `kind` is in LOG_STD_MAPS."""
  if kind not in LOG_STD_MAPS:
    raise ValueError(f'config.critic.log_std_map must be one of {LOG_STD_MAPS}, got {kind!r}')


def log_std_from(x: jnp.ndarray, kind: str) -> jnp.ndarray:
  """The actor's log-std from its raw output x (same shape) under the map `kind`."""
  check_log_std_map(kind)
  if kind == 'clip':
    return jnp.clip(x, LOG_STD_MIN, LOG_STD_MAX)
  return LOG_STD_MIN + 0.5 * (LOG_STD_MAX - LOG_STD_MIN) * (jnp.tanh(x) + 1.0)


class Actor(nn.Module):
  """Policy prior a = tanh(MLP(z)) in [-1, 1]^A.

  `stochastic`: the MLP also outputs a log-std, and `sample` draws the tanh-squashed Gaussian
  policy of SAC / TD-MPC2 (log-std in [-10, 2], TD-MPC2's bounds, through `log_std_map`, see
  LOG_STD_MAPS); calling the module gives its mode tanh(mean), which the planner and the
  actor-alone policy use.
  """
  hidden: tuple
  action_dim: int
  stochastic: bool = False
  log_std_map: str = 'clip'

  def setup(self):
    out = self.action_dim * (2 if self.stochastic else 1)
    self.mlp = MLP(tuple(self.hidden) + (out,))

  def __call__(self, z: jnp.ndarray) -> jnp.ndarray:
    return jnp.tanh(self.mlp(z)[..., :self.action_dim])

  def sample(self, z: jnp.ndarray, key: jax.Array):
    """z [..., D] -> (a [..., A] in (-1, 1), log pi(a|z) [...]), reparameterised."""
    out = self.mlp(z)
    mean = out[..., :self.action_dim]
    log_std = log_std_from(out[..., self.action_dim:], self.log_std_map)
    eps = jax.random.normal(key, mean.shape)
    u = mean + jnp.exp(log_std) * eps
    a = jnp.tanh(u)
    log_prob = jnp.sum(-0.5 * eps ** 2 - log_std - 0.5 * jnp.log(2 * jnp.pi)
                       - jnp.log(1.0 - a ** 2 + 1e-6), axis=-1)
    return a, log_prob


def weighted_bc_loss(a_pi: jnp.ndarray, action: jnp.ndarray,
                     weights: jnp.ndarray) -> jnp.ndarray:
  """mean(weights * ||a_pi - action||^2): a_pi, action [..., A], weights [...] -> []."""
  return jnp.mean(weights * jnp.sum((a_pi - action) ** 2, axis=-1))


def maxq_actor_loss(nets, params, z: jnp.ndarray, key: jax.Array,
                    entropy_coef: float) -> jnp.ndarray:
  """E[alpha log pi(a|z) - mean_j Q_j(z, a)], a ~ pi(.|z) reparameterised (SAC, TD-MPC2).

  z [..., D] (detached by the caller); Q's parameters are held fixed, so only the actor learns
  from it; Q in value_scale units is O(1), as TD-MPC2's scale-normalised Q.
  """
  a, log_prob = nets.actor.apply({'params': params['actor']}, z, key, method=nets.actor.sample)
  q = nets.critics.apply({'params': jax.lax.stop_gradient(params['critics'])}, z, a,
                         method=nets.critics.q_value)
  return jnp.mean(entropy_coef * log_prob - jnp.mean(q, axis=0))


class AWR:
  """Advantage-weighted regression on detached latents: the weights do not drive the encoder
  (as TD-MPC2's policy loss)."""
  stochastic = False
  needs_critics = True
  value = None

  def loss(self, losses: LossSettings, nets, params, z, action, weights, key):
    a_pi = nets.actor.apply({'params': params['actor']}, jax.lax.stop_gradient(z[:, :-1]))
    return weighted_bc_loss(a_pi, action, weights)


class BC:
  """Behaviour cloning, MSE on a_i from enc(o_i), i <= H."""
  stochastic = False
  needs_critics = False
  value = None

  def loss(self, losses: LossSettings, nets, params, z, action, weights, key):
    a_pi = nets.actor.apply({'params': params['actor']}, z[:, :-1])
    return weighted_bc_loss(a_pi, action, jnp.ones(action.shape[:-1]))


class MaxQ:
  """Max Q plus entropy (TD-MPC2 / SAC), on detached latents and Q."""
  stochastic = True
  needs_critics = True
  value = 'expectile'  # Its Q ensemble is trained with the expectile value's critics.

  def loss(self, losses: LossSettings, nets, params, z, action, weights, key):
    return maxq_actor_loss(nets, params, jax.lax.stop_gradient(z[:, :-1]), key,
                           losses.entropy_coef)


ACTORS.register('awr', AWR())
ACTORS.register('bc', BC())
ACTORS.register('maxq', MaxQ())


def get(m: ModelSettings):
  """The entry of `critic.actor` (ValueError naming the kinds if unknown)."""
  return ACTORS.get(m.actor)
