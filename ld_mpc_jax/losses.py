"""Losses: symlog / two-hot discrete regression (TD-MPC2) and the joint LD-MPC loss."""

from typing import Callable

import jax
import jax.numpy as jnp
import ml_collections
import optax

from ld_mpc_jax import diffusion
from ld_mpc_jax.critics import make_critic_loss, objective_settings, window_returns
from ld_mpc_jax.models import Networks, dynamics_type, make_transition, proposal_type


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
  """-sum_k p_k log softmax(logits)_k over the last axis (optax.softmax_cross_entropy)."""
  return optax.softmax_cross_entropy(logits, target_probs)


def discounted_return(rewards: jnp.ndarray, terminal_value: jnp.ndarray,
                      gamma: float) -> jnp.ndarray:
  """J = sum_{i<H} gamma^i r_i + gamma^H V: rewards [..., H], terminal_value [...] -> [...]."""
  horizon = rewards.shape[-1]
  discounts = gamma ** jnp.arange(horizon, dtype=rewards.dtype)
  return jnp.sum(rewards * discounts, axis=-1) + gamma ** horizon * terminal_value


n_step_targets = window_returns  # The behaviour value's targets (ld_mpc_jax.critics).


def maxq_actor_loss(nets: Networks, params, z: jnp.ndarray, key: jax.Array,
                    entropy_coef: float) -> jnp.ndarray:
  """E[alpha log pi(a|z) - mean_j Q_j(z, a)], a ~ pi(.|z) reparameterised (SAC, TD-MPC2).

  z [..., D] (detached by the caller); Q's parameters are held fixed, so only the actor learns
  from it; Q in value_scale units is O(1), as TD-MPC2's scale-normalised Q.
  """
  a, log_prob = nets.actor.apply({'params': params['actor']}, z, key, method=nets.actor.sample)
  q = nets.critics.apply({'params': jax.lax.stop_gradient(params['critics'])}, z, a,
                         method=nets.critics.q_value)
  return jnp.mean(entropy_coef * log_prob - jnp.mean(q, axis=0))


def make_loss_fn(config: ml_collections.ConfigDict, nets: Networks) -> Callable:
  """Returns loss_fn(params, target_params, batch, key) -> (loss, metrics).

  batch: obs [B, H+2, obs_dim], action [B, H+1, A], reward [B, H+1]. The models see the first
  H + 1 observations (T = H + 1 = 5 in the reference); the one extra step only supplies the
  bootstrap of the value targets, so that the terminal value V(z_H) the planner uses is trained
  like every other position.
  L = w_dyn L_dyn + w_act L_act + w_rew L_rew + w_val L_val + w_actor L_actor, where
    L_dyn: denoising loss of z_{i+1} = sg(enc(o_{i+1})) given (enc(o_i), a_i), all i <= H
      (dynamics_type 'mlp': MSE of the prediction; 'diffusion_traj': denoising loss of the
      whole trajectory z_{1:H} given z_0 and a_{0:H-1});
    L_act: denoising loss of the action sequence a_{0:H} given enc(o_0) (single-step proposal
      kinds: of a_i given enc(o_i), all i <= H; 'mlp': Gaussian negative log-likelihood);
    L_rew: two-hot cross-entropy of r_i, i < H, read at the a_i tokens;
    L_val: two-hot cross-entropy of V(z_i), i <= H, against n-step targets
      sum_{j=i}^{H} gamma^(j-i) r_j + gamma^(H+1-i) V_ema(z_{H+1}), where V_ema is the EMA
      (target) network's terminal value on the window shifted by one step;
    L_actor: behaviour cloning of the actor prior, MSE on a_i from enc(o_i), i <= H.
  """
  m, w, pred = config.model, config.loss, config.diffusion.prediction
  gamma, h = config.gamma, config.horizon
  kind_p, kind_d = proposal_type(config), dynamics_type(config)
  o = objective_settings(config)
  policy = lambda params, z: nets.actor.apply({'params': params['actor']}, z)
  critic_loss = (make_critic_loss(config, nets.critics, policy)
                 if nets.critics is not None else None)
  transition = (make_transition(config, nets, steps=o.rollout_steps, eta=0.0)
                if o.latent_rollout else None)

  def dynamics_loss(params, z, action, key, rngs):
    """z [B, H+2, D], action [B, H+1, A] -> [] (mean over examples and latent features)."""
    b = z.shape[0]
    apply = lambda *args: nets.dynamics.apply({'params': params['dynamics']}, *args,
                                              deterministic=False, rngs=rngs)
    if kind_d == 'diffusion_traj':  # z_{1:H} given z_0 and a_{0:H-1}, as the planner uses it.
      target = jax.lax.stop_gradient(z[:, 1:h + 1])
      fn = lambda x_t, t: apply(x_t, t, z[:, 0], action[:, :h])
      return diffusion.denoising_loss(fn, target, key, pred).mean()
    # One-step kinds, teacher-forced over all H + 1 transitions at once.
    z_in = z[:, :-1].reshape(b * (h + 1), -1)
    a_in = action.reshape(b * (h + 1), -1)
    z_next = jax.lax.stop_gradient(z[:, 1:]).reshape(b * (h + 1), -1)
    if kind_d == 'mlp':
      z_pred = nets.dynamics.apply({'params': params['dynamics']}, z_in, a_in)
      return jnp.mean((z_pred - z_next) ** 2)
    fn = lambda x_t, t: apply(x_t, t, z_in, a_in)
    return diffusion.denoising_loss(fn, z_next, key, pred).mean()

  def proposal_loss(params, z, action, key, rngs):
    """Sequence kind: a_{0:H} given z_0. Single-step kinds: a_i given z_i, i <= H."""
    b = z.shape[0]
    if kind_p == 'diffusion_seq':
      fn = lambda a_t, t: nets.proposal.apply({'params': params['proposal']}, a_t, t, z[:, 0],
                                              deterministic=False, rngs=rngs)
      return diffusion.denoising_loss(fn, action[:, :h], key, pred).mean()
    z_in = z[:, :-1].reshape(b * (h + 1), -1)
    a_in = action.reshape(b * (h + 1), -1)
    if kind_p == 'mlp':  # Gaussian negative log-likelihood (constant dropped), per dimension.
      mean, log_std = nets.proposal.apply({'params': params['proposal']}, z_in)
      return jnp.mean(0.5 * ((a_in - mean) * jnp.exp(-log_std)) ** 2 + log_std)
    fn = lambda a_t, t: nets.proposal.apply({'params': params['proposal']}, a_t, t, z_in,
                                            deterministic=False, rngs=rngs)
    return diffusion.denoising_loss(fn, a_in[:, None], key, pred).mean()

  def model_rollout(params, z0, actions, key):
    """Latents of the dynamics model from z0 [B, D] under actions [B, H, A] -> [B, H+1, D]."""
    def step(z_cur, inputs):
      a, i = inputs
      z_next = transition(params, z_cur, a, jax.random.fold_in(key, i))
      return z_next, z_next
    # Unrolled: H is small, and one flat program trains about 10% faster on XLA:CPU than a
    # while loop and its backward pass (docs/scaling.md).
    _, zs = jax.lax.scan(step, z0, (jnp.swapaxes(actions, 0, 1), jnp.arange(h)), unroll=True)
    return jnp.concatenate([z0[:, None], jnp.swapaxes(zs, 0, 1)], axis=1)

  def objective_losses(params, target_params, z_sets, z_ema, action, reward, drop):
    """Reward and behaviour-value cross-entropies, averaged over the latent sets z_sets (each
    [B, H+1 or H+2, D]: encoder latents, and the model's when it rolls out), scored together in
    one call of the objective on a new leading axis [n, B, ...] (the batch axis stays second,
    so a data-parallel batch split is not moved)."""
    z_all = jnp.stack([z_i[:, :h + 1] for z_i in z_sets])  # [n, B, H+1, D]
    a_all = jnp.broadcast_to(action[:, :h], z_all.shape[:2] + action[:, :h].shape[1:])
    r_logits, v_logits = nets.objective.apply(
        {'params': params['objective']}, z_all, a_all, deterministic=False, rngs=drop)
    l_rew = soft_cross_entropy(r_logits, two_hot(reward[:, :h], m.num_bins, m.vmin,
                                                 m.vmax)).mean()
    if o.value != 'behaviour':
      return l_rew, jnp.zeros(()), jnp.zeros(())
    _, v_tgt_logits = nets.objective.apply({'params': target_params['objective']},
                                           z_ema[:, 1:], action[:, 1:])
    bootstrap = two_hot_decode(v_tgt_logits[:, -1], m.vmin, m.vmax)  # V_ema(z_{H+1}).
    v_target = jax.lax.stop_gradient(n_step_targets(reward, bootstrap, gamma))  # [B, H+1]
    l_val = soft_cross_entropy(v_logits, two_hot(v_target, m.num_bins, m.vmin, m.vmax)).mean()
    return l_rew, l_val, v_target.mean()

  def loss_fn(params, target_params, batch, key):
    obs, action, reward = batch['obs'], batch['action'], batch['reward']
    k_dyn, k_act, k_drop, k_roll, k_pi = jax.random.split(key, 5)
    drop = lambda i: {'dropout': jax.random.fold_in(k_drop, i)}  # One stream per network.
    sg = jax.lax.stop_gradient

    z = nets.encoder.apply({'params': params['encoder']}, obs)  # [B, H+2, D]
    z_ema = sg(nets.encoder.apply({'params': target_params['encoder']}, obs))

    l_dyn = dynamics_loss(params, z, action, k_dyn, drop(0))
    l_act = proposal_loss(params, z, action, k_act, drop(1))

    metrics = {}
    z_model, l_cons = None, jnp.zeros(())
    if o.latent_rollout:  # The objective also learns on the latents it scores when planning.
      z_roll = model_rollout(params, z[:, 0], action[:, :h], k_roll)
      l_cons = jnp.mean((z_roll[:, 1:] - sg(z[:, 1:h + 1])) ** 2)
      z_model = sg(z_roll)
    z_sets = (z,) if z_model is None else (z, z_model)
    l_rew, l_val, v_target_mean = objective_losses(params, target_params, z_sets, z_ema, action,
                                                   reward, drop(2))
    if o.value == 'behaviour':
      metrics['value_target_mean'] = v_target_mean

    l_q = l_v = jnp.zeros(())
    if critic_loss is not None:
      critic, weights, critic_metrics = critic_loss(params, target_params, z, z_ema, z_model,
                                                    action, reward)
      l_q, l_v = critic['q'], critic['v']
      metrics.update(critic_metrics)
    if o.actor == 'maxq':  # TD-MPC2 / SAC: max Q + entropy, on detached latents and Q.
      l_actor = maxq_actor_loss(nets, params, sg(z[:, :-1]), k_pi, o.entropy_coef)
    else:
      if o.actor == 'bc':
        weights, z_actor = jnp.ones(reward.shape), z[:, :-1]
      else:  # As TD-MPC2's policy loss, on detached latents: weights do not drive the encoder.
        z_actor = sg(z[:, :-1])
      a_pi = nets.actor.apply({'params': params['actor']}, z_actor)
      l_actor = jnp.mean(weights * jnp.sum((a_pi - action) ** 2, axis=-1))

    loss = (w.w_dyn * l_dyn + w.w_act * l_act + w.w_rew * l_rew + w.w_val * l_val
            + w.w_actor * l_actor + w.get('w_consistency', 0.0) * l_cons
            + w.get('w_q', 0.0) * l_q + w.get('w_v', 0.0) * l_v)
    metrics.update({'loss': loss, 'loss_dyn': l_dyn, 'loss_act': l_act, 'loss_rew': l_rew,
                    'loss_val': l_val, 'loss_actor': l_actor})
    if o.latent_rollout:
      metrics['loss_consistency'] = l_cons
    if critic_loss is not None:
      metrics.update({'loss_q': l_q, 'loss_v': l_v})
    return loss, metrics

  return loss_fn
