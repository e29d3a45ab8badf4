"""A reward learned from successes: the progress head Phi(z) in (0, 1) (issue 70, the idea's
"reward design" where the environment's reward is sparse).

Phi is fitted by cross-entropy to each state's progress along an episode that succeeds, a
demonstration's or the agent's own: t / (t* + 1) for its t-th state, t* the action after which it
first succeeds, 1 from then on; 0 on the states of episodes that never succeed
(`ld_mpc_jax.data.replay.progress_targets`). DEMO3 (2025) learns such stage rewards from five
demonstrations; here one head on the latent, trained beside the model (`loss.w_progress`).

In J it enters as potential-based shaping (Ng, Harada and Russell 1999: it leaves the optimal
policy unchanged): r_i + w (gamma Phi(z_{i+1}) - Phi(z_i)) summed over the horizon telescopes to
w (gamma^H Phi(z_H) - Phi(z_0)), and Phi(z_0) is the same for every candidate sequence, so the
planner adds w gamma^H Phi(z_H) to each candidate's J (`plan.progress_weight` = w).
"""

import flax.linen as nn
import jax
import jax.numpy as jnp

from ld_mpc_jax.model.settings import ModelSettings
from ld_mpc_jax.nets import MLP


class Progress(nn.Module):
  """z [..., D] -> logit [...] of Phi(z) = sigmoid(logit)."""
  hidden: tuple

  @nn.compact
  def __call__(self, z: jnp.ndarray) -> jnp.ndarray:
    return MLP(tuple(self.hidden) + (1,), name='mlp')(z)[..., 0]


def build(m: ModelSettings) -> Progress:
  """The head of a model with the learned progress reward (`m.progress`: `loss.w_progress` > 0)."""
  return Progress(tuple(m.actor_hidden))


def loss(net: Progress, params: dict, z: jnp.ndarray, target: jnp.ndarray) -> jnp.ndarray:
  """Mean binary cross-entropy of Phi on the latents z [B, T, D] against targets [B, T] in
  [0, 1] -> []. The latents come in with their gradient stopped: the head reads the model's
  latent, it does not shape it."""
  logits = net.apply({'params': params['progress']}, jax.lax.stop_gradient(z))
  return jnp.mean(jnp.logaddexp(0.0, logits) - target * logits)  # -t log s - (1-t) log(1-s)


def phi(net: Progress, params: dict, z: jnp.ndarray) -> jnp.ndarray:
  """Phi(z) in (0, 1): z [..., D] -> [...]."""
  return jax.nn.sigmoid(net.apply({'params': params['progress']}, z))


def bonus(weight: float, gamma: float, net: Progress, params: dict,
          latents: jnp.ndarray) -> jnp.ndarray:
  """The shaping's part of J that differs between candidates: w gamma^H Phi(z_H) (w =
  `plan.progress_weight`), latents [K, H+1, D] -> [K]."""
  h = latents.shape[-2] - 1
  return weight * gamma ** h * phi(net, params, latents[..., -1, :])
