"""TD-MPC2's MLP world model, the baseline of the planning benchmark (ld_mpc_jax.plan.mppi runs
MPPI on it), beside this project's models.

It follows TD-MPC2's 5M configuration: latent 512 with SimNorm (groups of 8), encoder
39 -> 256 -> 512, dynamics / reward / policy / 5 Q-functions as 2-hidden-layer MLPs of width 512
with LayerNorm + Mish, 101-bin two-hot reward and Q heads. About 4.9M parameters.
"""

import dataclasses

import flax.linen as nn
import jax
import jax.numpy as jnp

from ld_mpc_jax.nets import MLP
from ld_mpc_jax.ops.numerics import two_hot_decode


@dataclasses.dataclass(frozen=True)
class TDMPC2Config:
  """Sizes of TD-MPC2's default (5M) model for a state-based task."""
  obs_dim: int = 39
  action_dim: int = 4
  latent_dim: int = 512
  enc_dim: int = 256
  mlp_dim: int = 512
  num_q: int = 5
  num_bins: int = 101
  vmin: float = -10.0
  vmax: float = 10.0
  simnorm_dim: int = 8
  log_std_min: float = -10.0
  log_std_max: float = 2.0
  gamma: float = 0.99


def simnorm(x: jnp.ndarray, group: int) -> jnp.ndarray:
  """Simplicial normalisation: softmax over consecutive groups of `group` features."""
  g = x.reshape(x.shape[:-1] + (-1, group))
  return jax.nn.softmax(g, axis=-1).reshape(x.shape)


class TDMPC2Model(nn.Module):
  """Encoder, latent dynamics, reward, policy and a Q ensemble (TD-MPC2's WorldModel)."""
  cfg: TDMPC2Config

  def setup(self):
    c = self.cfg
    hidden = (c.mlp_dim, c.mlp_dim)
    self.encoder = MLP((c.enc_dim, c.latent_dim))
    self.encoder_norm = nn.LayerNorm()
    self.dynamics = MLP(hidden + (c.latent_dim,))
    self.dynamics_norm = nn.LayerNorm()
    self.reward_head = MLP(hidden + (c.num_bins,))
    self.policy = MLP(hidden + (2 * c.action_dim,))
    self.qs = nn.vmap(MLP, variable_axes={'params': 0}, split_rngs={'params': True},
                      in_axes=None, out_axes=0, axis_size=c.num_q)(hidden + (c.num_bins,))

  def encode(self, obs):
    """obs [..., obs_dim] -> z [..., latent_dim] (SimNorm)."""
    return simnorm(self.encoder_norm(self.encoder(obs)), self.cfg.simnorm_dim)

  def next(self, z, a):
    """z [..., D], a [..., A] -> next latent [..., D] (SimNorm)."""
    h = self.dynamics(jnp.concatenate([z, a], axis=-1))
    return simnorm(self.dynamics_norm(h), self.cfg.simnorm_dim)

  def reward(self, z, a):
    """-> reward [...] decoded from two-hot logits."""
    logits = self.reward_head(jnp.concatenate([z, a], axis=-1))
    return two_hot_decode(logits, self.cfg.vmin, self.cfg.vmax)

  def pi(self, z, key):
    """z [..., D] -> sampled action tanh(mu + std eps) [..., A]."""
    mu, log_std = jnp.split(self.policy(z), 2, axis=-1)
    c = self.cfg
    log_std = c.log_std_min + 0.5 * (c.log_std_max - c.log_std_min) * (jnp.tanh(log_std) + 1)
    return jnp.tanh(mu + jnp.exp(log_std) * jax.random.normal(key, mu.shape))

  def q_all(self, z, a):
    """-> Q values of every ensemble member [num_q, ...]."""
    logits = self.qs(jnp.concatenate([z, a], axis=-1))
    return two_hot_decode(logits, self.cfg.vmin, self.cfg.vmax)

  def __call__(self, obs, a, key):  # For init only: touches every submodule.
    z = self.encode(obs)
    return self.next(z, a), self.reward(z, a), self.pi(z, key), self.q_all(z, a)


def init_tdmpc2_params(cfg: TDMPC2Config, key: jax.Array) -> dict:
  """Parameters of TDMPC2Model (a pytree)."""
  model = TDMPC2Model(cfg)
  init_key, call_key = jax.random.split(key)
  return model.init(init_key, jnp.zeros((1, cfg.obs_dim)), jnp.zeros((1, cfg.action_dim)),
                    call_key)['params']
