"""A learned exploration value: novelty that the planner can see beyond its horizon (issue 70,
exploration that seeks what the model does not know, for runs without demonstrations).

The acting planner's disagreement term (objective.Intrinsic.disagreement) only sees the H steps
it rolls out, and with a flat J it steers towards whatever the next few latents dispute. Here,
as in Plan2Explore (Sekar et al. 2020), the novelty is also learned into a value:

  members  E small MLPs f_e(z_t, a_t) ~ z_{t+1}, each fitted to the encoder's next latent (the
           same windows, different initialisations: an ensemble whose spread is epistemic, large
           where the buffer holds few transitions like this one);
  r_nov    the variance over the members of their predictions, mean over the latent dimensions;
  V_nov    an MLP of z fitted to the window's discounted r_nov, bootstrapped on its own
           (stop-gradient) value after the window (`numerics.window_returns`).

Both read the encoder's clean latents with their gradient stopped: they never shape the latent.
With `model.novelty_target='obs'` the members predict the observation's next change instead,
each coordinate divided by its spread in the batch (plus OBS_SCALE_FLOOR): the latent is scaled
by the hand that moves at every step, and a door that has barely moved is a small direction of
it, while here a door coordinate that moved in a few transitions counts as much as the hand.
While acting, `bonus` adds w x N to each candidate's J, N = sum_{i<H} gamma^i r_nov(z_i, a_i) +
gamma^H V_nov(z_H) divided by its mean over the candidates (so w is in units of the average
candidate's novelty, whatever the scale of r_nov as the ensemble learns); w is
`online.act_novelty`, annealed like the other intrinsic weights (ld_mpc_jax.online.schedule).
Evaluation never adds it.
"""

import flax.linen as nn
import jax
import jax.numpy as jnp

from ld_mpc_jax.model.objective import stable_std
from ld_mpc_jax.model.settings import ModelSettings
from ld_mpc_jax.nets import MLP
from ld_mpc_jax.ops.numerics import window_returns


class Novelty(nn.Module):
  """The members and the value: `__call__(z [..., D], a [..., A]) -> [E, ..., out_dim]` (each
  member's predicted next latent, or observation change for `target` 'obs') and
  `value(z [..., D]) -> [...]`."""
  members: int
  hidden: tuple
  out_dim: int
  target: str = 'latent'  # What the members predict (model.novelty_target).

  def setup(self):
    self.nets = [MLP(tuple(self.hidden) + (self.out_dim,), name=f'member_{e}')
                 for e in range(self.members)]
    self.value_net = MLP(tuple(self.hidden) + (1,), name='value')

  def __call__(self, z: jnp.ndarray, a: jnp.ndarray) -> jnp.ndarray:
    x = jnp.concatenate([z, a], axis=-1)
    return jnp.stack([net(x) for net in self.nets])

  def value(self, z: jnp.ndarray) -> jnp.ndarray:
    return self.value_net(z)[..., 0]

  def init_all(self, z: jnp.ndarray, a: jnp.ndarray):
    """Touches every submodule (for init): the members and the value."""
    return self(z, a), self.value(z)


# Added to each coordinate's batch spread of the observation's change (the units of
# 'obs'-target members): Meta-World's positions are in metres, so 1 mm per step; a coordinate
# that never moves in the batch is then fitted to 0, not divided by 0.
OBS_SCALE_FLOOR = 1e-3


def build(m: ModelSettings) -> Novelty:
  """The members and value of a model with the learned exploration value (`m.novelty`:
  `loss.w_novelty` > 0); `model.novelty_target` 'obs' predicts the observation's next change,
  'latent' the next latent."""
  out = m.obs_dim if m.novelty_target == 'obs' else m.latent_dim
  return Novelty(m.novelty_members, tuple(m.actor_hidden), out, m.novelty_target)


def init(net: Novelty, key: jax.Array, latent_dim: int, action_dim: int) -> dict:
  return net.init(key, jnp.zeros((1, latent_dim)), jnp.zeros((1, action_dim)),
                  method=Novelty.init_all)['params']


def _spread(preds: jnp.ndarray) -> jnp.ndarray:
  """The members' predictions [E, ..., D] (or [E, ..., O]) -> their variance, mean over the last
  axis [...]; exactly 0 where they agree (`objective.stable_std`)."""
  return jnp.mean(stable_std(preds, axis=0) ** 2, axis=-1)


def reward(net: Novelty, params: dict, z: jnp.ndarray, a: jnp.ndarray) -> jnp.ndarray:
  """r_nov(z, a): the members' variance about the next latent (or observation change), mean over
  its dimensions: z [..., D], a [..., A] -> [...]; exactly 0 where the members agree."""
  return _spread(net.apply({'params': params['novelty']}, z, a))


def value(net: Novelty, params: dict, z: jnp.ndarray) -> jnp.ndarray:
  """V_nov(z): z [..., D] -> [...]."""
  return net.apply({'params': params['novelty']}, z, method=Novelty.value)


def obs_targets(obs: jnp.ndarray) -> jnp.ndarray:
  """The 'obs'-target members' targets: obs [B, T+1, O] -> its change [B, T, O], each
  coordinate divided by its standard deviation over the batch plus OBS_SCALE_FLOOR."""
  change = obs[:, 1:] - obs[:, :-1]
  return change / (jnp.std(change, axis=(0, 1)) + OBS_SCALE_FLOOR)


def loss(net: Novelty, params: dict, z: jnp.ndarray, action: jnp.ndarray,
         gamma: float, obs: jnp.ndarray | None = None) -> jnp.ndarray:
  """The members' mean squared error about the next latent (members of `target` 'obs': about
  the window's `obs_targets`, obs [B, T+1, O]) plus V_nov's squared error against the window's
  novelty returns: z [B, T+1, D] (clean latents), action [B, >= T, A] -> []. The latents come in
  with their gradient stopped here."""
  z = jax.lax.stop_gradient(z)
  t = z.shape[1] - 1
  zt, at = z[:, :-1], action[:, :t]
  if net.target == 'obs' and obs is None:
    raise ValueError("novelty members with target 'obs' need the window's observations")
  target = jax.lax.stop_gradient(obs_targets(obs)) if net.target == 'obs' else z[:, 1:]
  preds = net.apply({'params': params['novelty']}, zt, at)  # [E, B, T, D]
  members = jnp.mean((preds - target[None]) ** 2)
  v = value(net, params, z)  # [B, T+1]: V_nov(z_t), then the bootstrap after the window.
  sg = jax.lax.stop_gradient
  returns = window_returns(sg(_spread(preds)), sg(v[:, -1]), gamma)  # [B, T]
  return members + jnp.mean((v[:, :-1] - returns) ** 2)


def bonus(net: Novelty, params: dict, latents: jnp.ndarray, actions: jnp.ndarray,
          gamma: float) -> jnp.ndarray:
  """N per candidate, scaled to mean 1 over the candidates: latents [N, H+1, D], actions
  [N, H, A] -> [N]; 0 where no candidate has any novelty."""
  h = actions.shape[-2]
  r = reward(net, params, latents[..., :-1, :], actions)  # [N, H]
  n = jnp.sum(gamma ** jnp.arange(h) * r, axis=-1) + gamma ** h * value(net, params,
                                                                          latents[..., -1, :])
  n = jnp.maximum(n, 0.0)  # V_nov regresses non-negative returns; keep its small errors out.
  return n / jnp.maximum(jnp.mean(n), 1e-12)
