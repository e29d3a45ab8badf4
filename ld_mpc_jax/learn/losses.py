"""The joint LD-MPC loss, a weighted sum of named terms.

batch: obs [B, H+2, obs_dim], action [B, H+1, A], reward [B, H+1]. The models see the first
H + 1 observations (T = H + 1 = 5 in the reference); the one extra step only supplies the
bootstrap of the value targets, so that the terminal value V(z_H) the planner uses is trained
like every other position.

  L = w_dyn L_dyn + w_act L_act + w_rew L_rew + w_val L_val + w_actor L_actor
      + w_consistency L_cons + w_q L_q + w_v L_v,

  L_dyn    the dynamics kind's loss (ld_mpc_jax.model.dynamics; z_{i+1} = sg(enc(o_{i+1})));
           like L_act, left out (not computed) where its weight is 0;
  L_act    the proposal kind's loss (ld_mpc_jax.model.proposals), each window alike or, with
           `loss.act_weighting='advantage'`, by the critics' weight of its first action; on the
           executed actions or, with `loss.act_target='planned'`, on the planner's sequences
           where the window has one (`proposal_targets`);
  L_rew    two-hot cross-entropy of r_i, i < H, read at the a_i tokens (`reward_loss`);
  L_val    the value kind's loss on the objective's value head ('behaviour', ld_mpc_jax.model.objective;
           0 for 'expectile', whose values are the critics');
  L_actor  the actor kind's loss (ld_mpc_jax.model.actors);
  L_cons   latent consistency of the model's rollout (`critic.latent_rollout`, TD-MPC2);
  L_q, L_v the critics' TD and expectile losses (ld_mpc_jax.model.critics), when the model has them;
  L_demo_bc behaviour cloning of the actor prior on the demonstrations' windows (batch['demo']
           [B], 1.0 on a demonstration's window; online runs with `online.demos`, MoDem), on
           detached latents, + w_demo_bc L_demo_bc in L;
  L_noise_inv with `train.obs_noise_aug` > 0 the models see enc(o + noise) (noise ~ N(0, aug^2)
           on every observation of the window) and this term, |enc(o + noise) - sg(enc(o))|^2,
           pulls a noisy observation's latent onto the clean one's; the consistency and value
           targets are encoded from the clean o (+ w_noise_inv L_noise_inv in L).
  L_progress with the learned progress reward (`loss.w_progress` > 0, windows carrying
           'progress'): the progress head's cross-entropy on the clean, detached latents
           (ld_mpc_jax.model.progress; + w_progress L_progress in L).
  L_novelty with the learned exploration value (`loss.w_novelty` > 0): the novelty members'
           next-latent (or next observation change: model.novelty_target) error and V_nov's
           error against the window's novelty returns, on the clean, detached latents
           (ld_mpc_jax.model.novelty; + w_novelty L_novelty in L).
Metrics: 'loss' and 'loss_<term>' for each term the config uses, plus the critics' and the
value kind's own metrics.
"""

from typing import Callable, Dict

import jax
import jax.numpy as jnp

from ld_mpc_jax.model import actors, dynamics, novelty, objective, progress, proposals
from ld_mpc_jax.model.critics import make_critic_loss
from ld_mpc_jax.model.models import Networks
from ld_mpc_jax.model.pixels import random_shift
from ld_mpc_jax.model.settings import LossSettings, ModelSettings
from ld_mpc_jax.ops.numerics import soft_cross_entropy, two_hot

# Loss weight of each term (config.loss.<weight>), in the order they are summed.
WEIGHTS = (('dyn', 'w_dyn'), ('act', 'w_act'), ('rew', 'w_rew'), ('val', 'w_val'),
           ('actor', 'w_actor'), ('consistency', 'w_consistency'), ('q', 'w_q'), ('v', 'w_v'),
           ('demo_bc', 'w_demo_bc'), ('noise_inv', 'w_noise_inv'), ('progress', 'w_progress'),
           ('novelty', 'w_novelty'))


def reward_loss(r_logits: jnp.ndarray, reward: jnp.ndarray, num_bins: int, vmin: float,
                vmax: float, balance: float = 0.0) -> jnp.ndarray:
  """Mean two-hot cross-entropy of rewards: r_logits [..., B, H, bins], reward [B, H] -> [].

  `balance` (`loss.reward_balance`) reweights the rare class of a sparse reward: the batch's
  positive rewards get weight (n_zero / n_positive)^balance against 1 for the zero ones, then
  the weights are scaled to mean 1 (1: both classes weigh the same in total, as class-balanced
  losses do; 0: the plain mean). A batch without positive rewards is the plain mean."""
  ce = soft_cross_entropy(r_logits, two_hot(reward, num_bins, vmin, vmax))
  if balance == 0:
    return ce.mean()
  positive = (reward > 0).astype(ce.dtype)
  n_pos = positive.sum()
  ratio = (positive.size - n_pos) / jnp.maximum(n_pos, 1.0)
  weight = jnp.where(positive > 0, ratio ** balance, 1.0)
  weight = weight / weight.mean()
  return jnp.mean(ce * weight)


def consistency_loss(z_model: jnp.ndarray, z_target: jnp.ndarray) -> jnp.ndarray:
  """MSE of the model's latents z_{1:H} [B, H, D] against sg(encoder latents) [B, H, D]."""
  return jnp.mean((z_model - jax.lax.stop_gradient(z_target)) ** 2)


def weighted_sum(terms: Dict[str, jnp.ndarray], weights: LossSettings) -> jnp.ndarray:
  """sum of weights.w * terms[name] over WEIGHTS, in that order; absent terms count 0."""
  total = jnp.zeros(())
  for i, (name, field) in enumerate(WEIGHTS):
    term, weight = terms.get(name, jnp.zeros(())), getattr(weights, field)
    total = weight * term if i == 0 else total + weight * term
  return total


def demo_bc_loss(nets, params, z: jnp.ndarray, action: jnp.ndarray,
                 demo: jnp.ndarray) -> jnp.ndarray:
  """Mean over the demonstrations' windows of the actor prior's squared error:
  z [B, T, D], action [B, T, A], demo [B] (1.0 on a demonstration's window) -> []."""
  a_pi = nets.actor.apply({'params': params['actor']}, z)
  err = jnp.mean(jnp.sum((a_pi - action) ** 2, axis=-1), axis=-1)
  return jnp.sum(demo * err) / jnp.maximum(jnp.sum(demo), 1.0)


def make_model_rollout(m: ModelSettings, losses: LossSettings, nets: Networks) -> Callable:
  """rollout(params, z0 [B, D], actions [B, H, A], key) -> latents [B, H+1, D] of the dynamics
  model, `critic.rollout_steps` deterministic DDIM steps per transition, a scan over H unrolled
  or not (`critic.rollout_unroll`)."""
  transition = dynamics.make_transition(m, nets.dynamics, steps=losses.rollout_steps, eta=0.0)

  def rollout(params, z0, actions, key):
    def step(z_cur, inputs):
      a, i = inputs
      z_next = transition(params, z_cur, a, jax.random.fold_in(key, i))
      return z_next, z_next
    _, zs = jax.lax.scan(step, z0, (jnp.swapaxes(actions, 0, 1), jnp.arange(actions.shape[1])),
                         unroll=losses.rollout_unroll)
    return jnp.concatenate([z0[:, None], jnp.swapaxes(zs, 0, 1)], axis=1)

  return rollout


def make_objective_terms(m: ModelSettings, losses: LossSettings, nets: Networks) -> Callable:
  """terms(params, target_params, z_sets, z_ema, action, reward, rngs) -> ({'rew', 'val'}, metrics).

  The reward (and, for the 'behaviour' value kind, value) cross-entropies, averaged over the
  latent sets z_sets (each [B, >= H+1, D]: encoder latents, and the model's when it rolls out),
  scored in one call of the objective on a new leading axis [n, B, ...] (the batch axis stays
  second, so a data-parallel batch split is not moved)."""
  h, value_kind = m.horizon, objective.get(m)

  def terms(params, target_params, z_sets, z_ema, action, reward, rngs):
    z_all = jnp.stack([z_i[:, :h + 1] for z_i in z_sets])  # [n, B, H+1, D]
    a_all = jnp.broadcast_to(action[:, :h], z_all.shape[:2] + action[:, :h].shape[1:])
    r_logits, v_logits = nets.objective.apply(
        {'params': params['objective']}, z_all, a_all, deterministic=False, rngs=rngs)
    out = {'rew': reward_loss(r_logits, reward[:, :h], m.num_bins, m.vmin, m.vmax,
                              losses.reward_balance)}
    if value_kind.loss is None:
      return dict(out, val=jnp.zeros(())), {}
    out['val'], target_mean = value_kind.loss(m, nets, target_params, z_ema, action, reward,
                                              v_logits)
    return out, {'value_target_mean': target_mean}

  return terms


def _make_critic_loss(m: ModelSettings, losses: LossSettings, nets: Networks):
  """The critics' loss (make_critic_loss) given the actor prior's mode and its draws, or None
  for a model without critics."""
  if nets.critics is None:
    return None
  policy = lambda params, z: nets.actor.apply({'params': params['actor']}, z)
  sample = lambda params, z, k: nets.actor.apply({'params': params['actor']}, z, k,
                                                 method=nets.actor.sample)[0]
  return make_critic_loss(m, losses, nets.critics, policy, sample)


def _weighs_act(losses: LossSettings, has_critics: bool) -> bool:
  """Whether the proposal's loss weighs its windows by the critics' weights
  (`loss.act_weighting='advantage'`); a one-line ValueError for a model without critics."""
  if losses.act_weighting == 'advantage' and not has_critics:
    raise ValueError("config.loss.act_weighting='advantage' weights by the critics' "
                     'advantages: the model has none (config.critic.value or critic.actor needs them)')
  return losses.act_weighting == 'advantage'


def proposal_targets(batch: Dict[str, jnp.ndarray], action: jnp.ndarray, h: int) -> jnp.ndarray:
  """The actions [B, H+1, A] the proposal denoises under `loss.act_target='planned'`: each
  window's first H replaced by the planner's chosen sequence at its first decision
  (batch['plan'] [B, H, A], from online acting) where it has one (batch['has_plan'] [B], 1.0),
  else the executed ones; `action` itself for a batch without plans."""
  if 'plan' not in batch:  # Structure, not value: known when tracing.
    return action
  planned = jnp.where(batch['has_plan'][:, None, None] > 0, batch['plan'], action[:, :h])
  return jnp.concatenate([planned, action[:, h:]], axis=1)


def _critic_terms(critic_loss, terms, metrics, params, target_params, z, z_ema, z_sets, action,
                  reward, key):
  """The critics' terms and metrics added to `terms` and `metrics` (in place); returns their
  weights [B, H+1], or None for a model without critics (`critic_loss` None)."""
  if critic_loss is None:
    return None
  z_model = z_sets[1] if len(z_sets) > 1 else None
  critic, weights, critic_metrics = critic_loss(params, target_params, z, z_ema, z_model, action,
                                                reward, key)
  terms.update(critic)
  metrics.update(critic_metrics)
  return weights


def _drq(m: ModelSettings, obs: jnp.ndarray, key: jax.Array) -> jnp.ndarray:
  """DrQ for images (`conv` encoder): each image shifted at random, its own stream of `key`;
  the robot's state after the pixels and state observations as they are."""
  if m.encoder_type != 'conv':
    return obs
  return random_shift(obs, jax.random.fold_in(key, 102), m.image_size, m.image_channels, 4,
                      m.proprio_dim)


def make_loss_fn(m: ModelSettings, losses: LossSettings, nets: Networks) -> Callable:
  """Returns loss_fn(params, target_params, batch, key) -> (loss [], metrics {name: []}).

  The terms and their weights: the module docstring. `target_params` are the EMA parameters:
  their encoder gives the value targets' latents z_ema, their objective or critics the targets.
  """
  h, sg, aug = m.horizon, jax.lax.stop_gradient, losses.obs_noise_aug
  proposal, dyn, actor = proposals.get(m), dynamics.get(m), actors.get(m)
  critic_loss = _make_critic_loss(m, losses, nets)
  model_rollout = make_model_rollout(m, losses, nets) if losses.latent_rollout else None
  objective_terms = make_objective_terms(m, losses, nets)
  weigh_act = _weighs_act(losses, critic_loss is not None)
  planned = losses.act_target == 'planned'

  def loss_fn(params, target_params, batch, key):
    obs, action, reward = _drq(m, batch['obs'], key), batch['action'], batch['reward']
    k_dyn, k_act, k_drop, k_roll, k_pi = jax.random.split(key, 5)
    drop = lambda i: {'dropout': jax.random.fold_in(k_drop, i)}  # One stream per network.
    encode = lambda p, o: nets.encoder.apply({'params': p['encoder']}, o)
    z = z_clean = encode(params, obs)  # [B, H+2, D]
    terms = {}
    if aug > 0:  # A separate stream: the other keys stay those of a run without it.
      noise = jax.random.normal(jax.random.fold_in(key, 101), obs.shape, obs.dtype)
      z, z_clean = encode(params, obs + aug * noise), sg(z_clean)
      terms['noise_inv'] = consistency_loss(z, z_clean)
    z_ema = sg(encode(target_params, obs))
    # A term of weight 0 is left out, not computed (the TD-MPC2 control trains neither).
    if losses.w_dyn:
      terms['dyn'] = dyn.loss(m, nets.dynamics, params, z, action, k_dyn, drop(0))
    act_seq = proposal_targets(batch, action, h) if planned else action
    if losses.w_act and not weigh_act:
      terms['act'] = proposal.loss(m, nets.proposal, params, z, act_seq, k_act, drop(1))
    z_sets = (z,)
    if model_rollout is not None:  # The objective also learns on the latents it scores.
      z_roll = model_rollout(params, z[:, 0], action[:, :h], k_roll)
      terms['consistency'] = consistency_loss(z_roll[:, 1:], z_clean[:, 1:h + 1])
      z_sets = (z, sg(z_roll))
    obj_terms, metrics = objective_terms(params, target_params, z_sets, z_ema, action, reward,
                                         drop(2))
    terms.update(obj_terms)
    weights = _critic_terms(critic_loss, terms, metrics, params, target_params, z, z_ema, z_sets,
                            action, reward, jax.random.fold_in(key, 103))
    if losses.w_act and weigh_act:  # By the critics' weights, scaled to mean 1 over the batch.
      terms['act'] = proposal.loss(m, nets.proposal, params, z, act_seq, k_act, drop(1),
                                   weights=weights / jnp.maximum(jnp.mean(weights), 1e-8))
    terms['actor'] = actor.loss(losses, nets, params, z, action, weights, k_pi)
    if 'demo' in batch:  # Structure, not value: known when tracing.
      terms['demo_bc'] = demo_bc_loss(nets, params, sg(z[:, :-1]), action, batch['demo'])
    if 'progress' in batch and nets.progress is not None:  # The learned progress reward.
      terms['progress'] = progress.loss(nets.progress, params, z_clean, batch['progress'])
    if nets.novelty is not None:  # The learned exploration value.
      terms['novelty'] = novelty.loss(nets.novelty, params, z_clean, action, m.gamma, obs)
    loss = weighted_sum(terms, losses)
    metrics['loss'] = loss
    metrics.update({f'loss_{name}': terms[name] for name, _ in WEIGHTS if name in terms})
    return loss, metrics

  return loss_fn
