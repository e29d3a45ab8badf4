"""Losses: symlog / two-hot discrete regression (TD-MPC2) and the joint LD-MPC loss."""

from typing import Callable

import jax
import jax.numpy as jnp
import ml_collections

from ld_mpc_jax import diffusion
from ld_mpc_jax.models import Networks


def symlog(x: jnp.ndarray) -> jnp.ndarray:
  """sign(x) log(1 + |x|)."""
  return jnp.sign(x) * jnp.log1p(jnp.abs(x))


def symexp(x: jnp.ndarray) -> jnp.ndarray:
  """Inverse of symlog: sign(x) (exp|x| - 1)."""
  return jnp.sign(x) * jnp.expm1(jnp.abs(x))


def bin_centers(num_bins: int, vmin: float, vmax: float) -> jnp.ndarray:
  """[num_bins] evenly spaced bin centres in symlog space."""
  return jnp.linspace(vmin, vmax, num_bins)


def two_hot(x: jnp.ndarray, num_bins: int, vmin: float, vmax: float) -> jnp.ndarray:
  """Two-hot encoding of symlog(x) over bins on [vmin, vmax]: [...] -> [..., num_bins].

  The mass is split between the two nearest bins in proportion to proximity, so the expected
  bin value equals clip(symlog(x), vmin, vmax) exactly.
  """
  y = jnp.clip(symlog(x), vmin, vmax)
  pos = (y - vmin) / (vmax - vmin) * (num_bins - 1)
  lo = jnp.clip(jnp.floor(pos), 0, num_bins - 2)
  frac = pos - lo
  lo = lo.astype(jnp.int32)
  return (jax.nn.one_hot(lo, num_bins) * (1.0 - frac)[..., None]
          + jax.nn.one_hot(lo + 1, num_bins) * frac[..., None])


def two_hot_decode(logits: jnp.ndarray, vmin: float, vmax: float) -> jnp.ndarray:
  """Scalar prediction of two-hot logits [..., num_bins] -> [...]: symexp(E_softmax[bin])."""
  centers = bin_centers(logits.shape[-1], vmin, vmax)
  return symexp(jnp.sum(jax.nn.softmax(logits, axis=-1) * centers, axis=-1))


def soft_cross_entropy(logits: jnp.ndarray, target_probs: jnp.ndarray) -> jnp.ndarray:
  """-sum_k p_k log softmax(logits)_k over the last axis."""
  return -jnp.sum(target_probs * jax.nn.log_softmax(logits, axis=-1), axis=-1)


def discounted_return(rewards: jnp.ndarray, terminal_value: jnp.ndarray,
                      gamma: float) -> jnp.ndarray:
  """J = sum_{i<H} gamma^i r_i + gamma^H V: rewards [..., H], terminal_value [...] -> [...]."""
  horizon = rewards.shape[-1]
  discounts = gamma ** jnp.arange(horizon, dtype=rewards.dtype)
  return jnp.sum(rewards * discounts, axis=-1) + gamma ** horizon * terminal_value


def n_step_targets(rewards: jnp.ndarray, bootstrap: jnp.ndarray, gamma: float) -> jnp.ndarray:
  """Targets for V(z_i), i < H: sum_{j=i}^{H-1} gamma^(j-i) r_j + gamma^(H-i) bootstrap.

  rewards [..., H], bootstrap [...] (value of z_H) -> [..., H].
  """
  def step(carry, r):
    g = r + gamma * carry
    return g, g
  _, out = jax.lax.scan(step, bootstrap, jnp.moveaxis(rewards, -1, 0), reverse=True)
  return jnp.moveaxis(out, 0, -1)


def make_loss_fn(config: ml_collections.ConfigDict, nets: Networks) -> Callable:
  """Returns loss_fn(params, target_params, batch, key) -> (loss, metrics).

  batch: obs [B, H+1, obs_dim], action [B, H, A], reward [B, H].
  L = w_dyn L_dyn + w_act L_act + w_rew L_rew + w_val L_val + w_actor L_actor, where
    L_dyn: denoising loss of z_{i+1} = sg(enc(o_{i+1})) given (enc(o_i), a_i), all i < H;
    L_act: denoising loss of the action sequence a_{0:H} given enc(o_0);
    L_rew, L_val: two-hot soft cross-entropies of the sequence objective model;
    L_actor: behaviour cloning of the actor prior, MSE on a_i from enc(o_i).
  Value targets come from `target_params` (the EMA parameters), never differentiated.
  """
  m, w, pred = config.model, config.loss, config.diffusion.prediction
  gamma = config.gamma

  def loss_fn(params, target_params, batch, key):
    obs, action, reward = batch['obs'], batch['action'], batch['reward']
    b, h1 = obs.shape[:2]
    h = h1 - 1
    k_dyn, k_act, k_drop = jax.random.split(key, 3)
    drop = lambda i: {'dropout': jax.random.fold_in(k_drop, i)}  # One stream per network.

    z = nets.encoder.apply({'params': params['encoder']}, obs)  # [B, H+1, D]

    # Latent dynamics, teacher-forced over all H transitions at once.
    z_in = z[:, :-1].reshape(b * h, -1)
    a_in = action.reshape(b * h, -1)
    z_next = jax.lax.stop_gradient(z[:, 1:]).reshape(b * h, -1)
    dyn_fn = lambda x_t, t: nets.dynamics.apply(
        {'params': params['dynamics']}, x_t, t, z_in, a_in, deterministic=False,
        rngs=drop(0))
    l_dyn = diffusion.denoising_loss(dyn_fn, z_next, k_dyn, pred).mean()

    # Action proposal: the whole H-step sequence given z_0.
    act_fn = lambda a_t, t: nets.proposal.apply(
        {'params': params['proposal']}, a_t, t, z[:, 0], deterministic=False,
        rngs=drop(1))
    l_act = diffusion.denoising_loss(act_fn, action, k_act, pred).mean()

    # Sequence objective: rewards at a_i tokens, values at z_i tokens.
    r_logits, v_logits = nets.objective.apply(
        {'params': params['objective']}, z, action, deterministic=False, rngs=drop(2))
    l_rew = soft_cross_entropy(r_logits, two_hot(reward, m.num_bins, m.vmin, m.vmax)).mean()

    z_tgt = nets.encoder.apply({'params': target_params['encoder']}, obs)
    _, v_tgt_logits = nets.objective.apply({'params': target_params['objective']}, z_tgt, action)
    bootstrap = two_hot_decode(v_tgt_logits[:, -1], m.vmin, m.vmax)
    v_target = jax.lax.stop_gradient(n_step_targets(reward, bootstrap, gamma))  # [B, H]
    l_val = soft_cross_entropy(v_logits[:, :-1],
                               two_hot(v_target, m.num_bins, m.vmin, m.vmax)).mean()

    a_pi = nets.actor.apply({'params': params['actor']}, z[:, :-1])
    l_actor = jnp.mean(jnp.sum((a_pi - action) ** 2, axis=-1))

    loss = (w.w_dyn * l_dyn + w.w_act * l_act + w.w_rew * l_rew + w.w_val * l_val
            + w.w_actor * l_actor)
    metrics = {'loss': loss, 'loss_dyn': l_dyn, 'loss_act': l_act, 'loss_rew': l_rew,
               'loss_val': l_val, 'loss_actor': l_actor,
               'value_target_mean': v_target.mean()}
    return loss, metrics

  return loss_fn
