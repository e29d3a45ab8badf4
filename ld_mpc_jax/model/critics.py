"""Values of the best policy in the data's support, on latents: IQL-style expectile regression.

The sequence objective's own value head (`config.critic.value = 'behaviour'`) regresses
n-step returns of the data, so it values the behaviour policy, and it reads V(z_H) through a
causal transformer that also sees the action prefix. With `value = 'expectile'` (the default)
the terminal value comes from an ensemble of MLPs of z_H alone, trained as in IQL (Kostrikov et
al. 2022, "Offline RL with Implicit Q-Learning"):
  L_Q = E (r_t + gamma V_ema(z'_{t+1}) - Q(z_t, a_t))^2                    (TD, EMA target)
(`critic.td_target = 'one_step'`; the default 'window' regresses Q onto the discounted rewards
to the end of the training window plus V_ema there: n-step propagation, with the data's actions
after the first, which short trainings need),
  L_V = E L_tau(min_j Q_ema(z'_t, a_t) - V(z_t)),  L_tau(u) = |tau - 1(u < 0)| u^2
where z' are the EMA encoder's latents. An upper expectile (tau > 0.5) of Q over the data's
actions approaches the value of the best action the data contain, without querying Q outside
them. The actor prior is then extracted by advantage-weighted regression (AWR, Peng et al. 2019;
IQL eq. 7): weights min(exp(beta (Q_ema - V)), w_max) on the behaviour-cloning error.
How the terminal value enters J: ld_mpc_jax.model.objective; the actor kinds: ld_mpc_jax.model.actors.

Values are predicted in units of `config.critic.value_scale` (Meta-World rewards are up to
10 per step, so returns reach hundreds); expectile regression is equivariant to that scale.
"""

from typing import Callable, Dict, Optional

import flax.linen as nn
import jax
import jax.numpy as jnp

from ld_mpc_jax.model.settings import LossSettings, ModelSettings
from ld_mpc_jax.nets import MLP
from ld_mpc_jax.ops.numerics import soft_cross_entropy, two_hot, two_hot_decode, window_returns

# Q's target (`config.critic.td_target`): 'one_step' r_t + gamma V_ema(z'_{t+1}) (IQL);
# 'window' the discounted rewards to the window's end plus V_ema there; 'policy': Q <- r_t +
# gamma min_j Q_ema(z'_{t+1}, pi(z'_{t+1})) and V(z) <- min_j Q_ema(z, pi(z)) (TD-MPC2): values
# of the current policy, which extrapolate beyond the data's actions; 'tdmpc2': TD-MPC2's own,
# Q <- r_t + gamma min of two random target members at (z_{t+1}, a ~ pi(z_{t+1})), z the online
# encoder's latents (detached), and V(z) <- the mean of two random target members at
# (z, a ~ pi(z)) (its planner's terminal value, `tdmpc2_q_target`).
TD_TARGETS = ('one_step', 'window', 'policy', 'tdmpc2')
# The heads of the V and Q members (`config.critic.heads`): 'scalar' (MSE in value_scale units)
# or 'two_hot' (logits over model.num_bins symlog bins, cross-entropy, as TD-MPC2's Q).
CRITIC_HEADS = ('scalar', 'two_hot')


class Ensemble(nn.Module):
  """`num` independent MLPs: x [..., d] -> [num, ...] (scalar output, `bins` = 0) or logits
  [num, ..., bins]."""
  hidden: tuple
  num: int
  bins: int = 0

  @nn.compact
  def __call__(self, x: jnp.ndarray) -> jnp.ndarray:
    heads = nn.vmap(MLP, variable_axes={'params': 0}, split_rngs={'params': True},
                    in_axes=None, out_axes=0, axis_size=self.num)
    out = heads(tuple(self.hidden) + (self.bins or 1,), name='heads')(x)
    return out if self.bins else out[..., 0]


class Critics(nn.Module):
  """V(z) ensemble and Q(z, a) ensemble, in value_scale units; with `bins` > 0 two-hot heads
  (logits over symlog bins on [vmin, vmax]; `value` and `q_value` decode them)."""
  hidden: tuple
  num_values: int
  num_q: int
  bins: int = 0
  vmin: float = -10.0
  vmax: float = 10.0

  def setup(self):
    self.v = Ensemble(self.hidden, self.num_values, self.bins)
    self.q = Ensemble(self.hidden, self.num_q, self.bins)

  def _decode(self, out: jnp.ndarray) -> jnp.ndarray:
    return decode_head(self, out)

  def value_logits(self, z: jnp.ndarray) -> jnp.ndarray:
    """z [..., D] -> [num_values, ...] (scalar heads) or [num_values, ..., bins] (two-hot)."""
    return self.v(z)

  def q_logits(self, z: jnp.ndarray, a: jnp.ndarray) -> jnp.ndarray:
    """z [..., D], a [..., A] -> [num_q, ...] or [num_q, ..., bins], as value_logits."""
    return self.q(jnp.concatenate([z, a], axis=-1))

  def value(self, z: jnp.ndarray) -> jnp.ndarray:
    """z [..., D] -> [num_values, ...]."""
    return self._decode(self.value_logits(z))

  def q_value(self, z: jnp.ndarray, a: jnp.ndarray) -> jnp.ndarray:
    """z [..., D], a [..., A] -> [num_q, ...]."""
    return self._decode(self.q_logits(z, a))

  def __call__(self, z, a):
    return self.value(z), self.q_value(z, a)


def decode_head(critics: Critics, out: jnp.ndarray) -> jnp.ndarray:
  """A head's output as values in value_scale units: two-hot logits [num, ..., bins] decoded,
  scalar heads' [num, ...] as they are."""
  return two_hot_decode(out, critics.vmin, critics.vmax) if critics.bins else out


def build_critics(m: ModelSettings) -> Critics:
  """The V and Q ensembles of `config.critic` (whether a model has them: models.uses_critics)."""
  bins = m.num_bins if m.critic_heads == 'two_hot' else 0
  return Critics(tuple(m.critic_hidden), m.num_values, m.num_q, bins, m.vmin, m.vmax)


def random_pair(key: jax.Array, num: int) -> jnp.ndarray:
  """[2] int32: two distinct members of an ensemble of `num`, drawn uniformly (TD-MPC2 draws one
  pair per update, torch.randperm(num_q)[:2])."""
  return jax.random.permutation(key, num)[:2]


def tdmpc2_q_target(reward: jnp.ndarray, q_next: jnp.ndarray, gamma: float,
                    pair: jnp.ndarray) -> jnp.ndarray:
  """TD-MPC2's TD target r + gamma min(Q_i, Q_j) of the `pair` (i, j) of target members:
  reward [...], q_next [num_q, ...] (the target members at (z', pi(z'))) -> [...]."""
  return reward + gamma * jnp.min(q_next[pair], axis=0)


def head_loss(critics: Critics, out: jnp.ndarray, target: jnp.ndarray) -> jnp.ndarray:
  """Mean over members and positions: out [num, ...] (or logits [num, ..., bins]) against
  target [...]: squared error, or with two-hot heads the cross-entropy of two_hot(target)."""
  if not critics.bins:
    return jnp.mean((out - target) ** 2)
  probs = two_hot(target, critics.bins, critics.vmin, critics.vmax)
  return jnp.mean(soft_cross_entropy(out, probs))


def expectile_loss(diff: jnp.ndarray, expectile: float) -> jnp.ndarray:
  """L_tau(u) = |tau - 1(u < 0)| u^2, elementwise; diff = target - prediction."""
  weight = jnp.where(diff < 0, 1.0 - expectile, expectile)
  return weight * diff ** 2


def awr_weights(advantage: jnp.ndarray, temperature: float, max_weight: float) -> jnp.ndarray:
  """min(exp(temperature * advantage), max_weight), elementwise (IQL's clip at 100)."""
  return jnp.minimum(jnp.exp(temperature * advantage), max_weight)


def _tdmpc2_targets(apply, sample, params, target_params, z, reward, gamma, num_q, key):
  """(Q target [B, H+1], V target [B, H+1]) of `critic.td_target='tdmpc2'`: the online latents
  z [B, H+2, D] detached, actions sampled from the policy, pairs of target members drawn with
  split(key, 4): (Q's pair, V's pair, next actions, actions)."""
  sg = jax.lax.stop_gradient
  k_pair, k_vpair, k_next, k_now = jax.random.split(key, 4)
  z, h1 = sg(z), reward.shape[-1]
  q_next = apply(target_params, z[:, 1:], sg(sample(params, z[:, 1:], k_next)),
                 method=Critics.q_value)
  q_target = tdmpc2_q_target(reward, q_next, gamma, random_pair(k_pair, num_q))
  q_now = apply(target_params, z[:, :h1], sg(sample(params, z[:, :h1], k_now)),
                method=Critics.q_value)
  v_target = jnp.mean(q_now[random_pair(k_vpair, num_q)], axis=0)
  return sg(q_target), sg(v_target)


def make_critic_loss(m: ModelSettings, losses: LossSettings, critics: Critics,
                     policy: Optional[Callable] = None,
                     sample: Optional[Callable] = None) -> Callable:
  """Returns critic_loss(params, target_params, z, z_ema, z_model, action, reward, key=None).

  policy(params, z [..., D]) -> a [..., A]: the actor prior's action, needed by
  `critic.td_target = 'policy'` (TD-MPC2's targets: Q onto r + gamma min Q_ema(z', pi(z')),
  V onto min Q_ema(z, pi(z)) by squared error instead of the expectile); sample(params, z, key)
  -> a: a draw of the stochastic policy, and `key`, needed by 'tdmpc2' (`_tdmpc2_targets`).
  With two-hot heads (`critic.heads`) the squared errors are cross-entropies (`head_loss`).

  z, z_ema [B, H+2, D]: online and EMA encoder latents of the window; z_model [B, H+1, D] or
  None: the dynamics model's latents from z_0 under the data's actions (stop-gradient), on which
  V is trained as well, since that is where the planner reads it. action [B, H+1, A], reward
  [B, H+1]. -> (losses {'q', 'v'}, awr_weights [B, H+1], metrics).
  """
  o, gamma, h, scale = losses, m.gamma, m.horizon, m.value_scale
  apply = lambda p, *args, method: critics.apply({'params': p['critics']}, *args, method=method)

  def critic_loss(params, target_params, z, z_ema, z_model, action, reward, key=None):
    sg, decode = jax.lax.stop_gradient, lambda out: decode_head(critics, out)
    z_t, ze_t = z[:, :h + 1], z_ema[:, :h + 1]
    v_next = jnp.mean(apply(target_params, z_ema[:, 1:], method=Critics.value), axis=0)
    on_policy = o.td_target in ('policy', 'tdmpc2')
    if o.td_target == 'tdmpc2':  # TD-MPC2's own: pairs of target members, sampled actions.
      q_target, q_pi = _tdmpc2_targets(apply, sample, params, target_params, z, reward / scale,
                                       gamma, m.num_q, key)
    elif on_policy:  # TD-MPC2: the next action from the policy, the min over target Qs.
      q_next = jnp.min(apply(target_params, z_ema[:, 1:], sg(policy(params, z_ema[:, 1:])),
                             method=Critics.q_value), axis=0)
      q_target = sg(reward / scale + gamma * q_next)
      q_pi = sg(jnp.min(apply(target_params, ze_t, sg(policy(params, ze_t)),
                              method=Critics.q_value), axis=0))
    elif o.td_target == 'window':  # n-step: rewards to the window's end.
      q_target = sg(window_returns(reward / scale, v_next[:, -1], gamma))
    else:
      q_target = sg(reward / scale + gamma * v_next)  # [B, H+1]
    q_out = apply(params, z_t, action, method=Critics.q_logits)  # [num_q, B, H+1(, bins)]
    l_q, q = head_loss(critics, q_out, q_target), decode(q_out)
    q_ema = sg(jnp.min(apply(target_params, ze_t, action, method=Critics.q_value), axis=0))
    # V on the encoder's latents and, where given, on the model's, in one call on a new leading
    # axis: [num_values, n, B, H+1]; the loss is the mean over both sets.
    z_sets = (z_t,) if z_model is None else (z_t, z_model)
    v_out = apply(params, jnp.stack(z_sets), method=Critics.value_logits)
    v = decode(v_out)[:, 0]  # [num_values, B, H+1], on the encoder's latents.
    if on_policy:  # V(z) = Q(z, pi(z)): the value of the policy, the planner's terminal value.
      l_v = head_loss(critics, v_out, jnp.stack([q_pi] * len(z_sets)))
    else:
      l_v = jnp.mean(expectile_loss(q_ema - decode(v_out), o.expectile))
    advantage = scale * (q_ema - sg(jnp.mean(v, axis=0)))  # reward units
    weights = awr_weights(advantage, o.awr_temperature, o.awr_max_weight)
    metrics: Dict[str, jnp.ndarray] = {
        'q_mean': scale * jnp.mean(q), 'v_mean': scale * jnp.mean(v),
        'advantage_std': jnp.std(advantage), 'awr_weight_mean': jnp.mean(weights)}
    return {'q': l_q, 'v': l_v}, sg(weights), metrics

  return critic_loss
