"""J, the planner's objective, in one place: what a candidate action sequence is worth.

  J_m = sum_{i<H} gamma^i r_i + gamma^H V_m(z_H)  under each value member m,
  J   = mean_m J_m - pessimism x std_m J_m        (`combine`, `plan.pessimism`; < 0 is optimism).

Rewards r_i come from the sequence objective network (two-hot, decoded); the terminal value
V_m(z_H) from the value kind (`config.critic.value`, one registry entry per kind):
  'expectile'  member m of the expectile V ensemble of z_H alone (ld_mpc_jax.model.critics), in
               reward units; M = `critic.num_values`;
  'behaviour'  the sequence objective's own value head read at z_H (n-step returns of the data,
               the behaviour policy's value); M = 1. Its loss term is `Behaviour.loss`.
The planner, MPPI on the learned model and the diagnostics all score with `make_score` or
`make_member_scores`; the planner averages J over dynamics draws with `make_score_draws`, which
adds the acting planner's intrinsic term (`Intrinsic`) when it is given one.
"""

from typing import Callable, Optional

import flax
import jax
import jax.numpy as jnp

from ld_mpc_jax.model import progress
from ld_mpc_jax.model.critics import Critics
from ld_mpc_jax.model.settings import ModelSettings
from ld_mpc_jax.ops.numerics import (discounted_return, soft_cross_entropy, two_hot, two_hot_decode,
                            window_returns)
from ld_mpc_jax.ops.registry import Registry

# score_fn(params, latents [K, H+1, D], actions [K, H, A]) -> J [K], or J per member [M, K].
ScoreFn = Callable[[dict, jnp.ndarray, jnp.ndarray], jnp.ndarray]

VALUES = Registry('value', 'config.critic.value')


def combine(members: jnp.ndarray, pessimism: float) -> jnp.ndarray:
  """Member scores [M, ...] -> [...]: mean - pessimism x std over the members (std 0 for M = 1)."""
  return jnp.mean(members, axis=0) - pessimism * jnp.std(members, axis=0)


def _centred(x: jnp.ndarray, axis: int) -> jnp.ndarray:
  """x minus its mean over `axis`, computed on the deviations from the first entry along it, so
  that it is exactly 0 where all entries are equal (the mean of equal floats can round away from
  them, and jnp.std's deviations would not be 0)."""
  dev = x - jax.lax.index_in_dim(x, 0, axis)
  return dev - jnp.mean(dev, axis=axis, keepdims=True)


def stable_std(x: jnp.ndarray, axis: int = 0) -> jnp.ndarray:
  """The std over `axis`; exactly 0 where all entries along it are equal (`_centred`)."""
  return jnp.sqrt(jnp.mean(_centred(x, axis) ** 2, axis=axis))


def latent_disagreement(latents: jnp.ndarray, gamma: float) -> jnp.ndarray:
  """[R, N, H+1, D] latents of N candidates under R dynamics draws -> [N]: sum_{i<H} gamma^i x
  the variance over the draws of z_{i+1}, averaged over the latent dimensions (Plan2Explore's
  ensemble variance of the next embedding, here over the dynamics model's stochastic draws);
  exactly 0 where the draws agree (one draw, or deterministic dynamics)."""
  per_step = jnp.mean(jnp.mean(_centred(latents[:, :, 1:], 0) ** 2, axis=0), axis=-1)  # [N, H]
  return jnp.sum(gamma ** jnp.arange(per_step.shape[-1]) * per_step, axis=-1)


@flax.struct.dataclass
class Intrinsic:
  """The acting planner's intrinsic term of J, traced scalars (annealing never recompiles;
  ld_mpc_jax.online.schedule schedules them; evaluation never passes one):

    J_act = J - pessimism x std_m(J_m) + disagreement x D + novelty x N,

  std_m the std over the value members (`stable_std`, mean over the dynamics draws): pessimism < 0 is an
  optimism bonus for what the ensemble disputes (UCB; OAC, Ciosek et al. 2019); D the dynamics
  draws' disagreement about the latents a candidate reaches (`latent_disagreement`; Plan2Explore,
  Sekar et al. 2020). Both are exactly 0 where the members and the draws agree. N the learned
  exploration value along draw 0's rollout, scaled to mean 1 over the candidates
  (ld_mpc_jax.model.novelty; only for a model that has it)."""
  pessimism: jnp.ndarray  # [] float32
  disagreement: jnp.ndarray  # [] float32
  novelty: jnp.ndarray = 0.0  # [] float32


def intrinsic_term(members: jnp.ndarray, latents: jnp.ndarray, intrinsic: Intrinsic,
                   gamma: float) -> jnp.ndarray:
  """members [R, M, N] and latents [R, N, H+1, D] of R dynamics draws -> [N]: what `Intrinsic`
  adds to J (the disagreement term only with R > 1)."""
  term = -intrinsic.pessimism * jnp.mean(stable_std(members, axis=1), axis=0)
  if latents.shape[0] > 1:
    term = term + intrinsic.disagreement * latent_disagreement(latents, gamma)
  return term


def make_score_draws(member_fn: ScoreFn, draws: int, pessimism: float,
                     gamma: float, novelty_fn: Optional[ScoreFn] = None) -> Callable:
  """score(params, z, proposals, key, roll, intrinsic=None) -> (actions [N, H, A], scores [N],
  members [draws x M, N]): J per draw combined over the value members (`combine`), averaged over
  `draws` rollouts of the same candidates, plus `intrinsic_term` when an `Intrinsic` is given
  (acting), and its novelty weight x `novelty_fn(params, latents [N, H+1, D], actions)` -> [N]
  on draw 0's rollout when there is one (ld_mpc_jax.model.novelty). `roll(params, z, proposals, key) -> (actions, latents [N, H+1, D])`; draw i rolls
  with fold_in(key, i); the draws run as one batch (vmap over their keys: the same draws as one
  after another, in one pass of the rollout's sequential steps)."""
  def score_draws(params, z, proposals_, key, roll, intrinsic=None):
    def one(i):
      acts, lats = roll(params, z, proposals_, jax.random.fold_in(key, i))
      return acts, member_fn(params, lats, acts), lats
    if draws == 1:
      actions, members, latents = one(0)
      scores, members, latents = combine(members, pessimism), members[None], latents[None]
    else:  # [draws, N, H, A], [draws, M, N], [draws, N, H+1, D]
      all_actions, members, latents = jax.vmap(one)(jnp.arange(draws))
      actions = all_actions[0]  # Draw 0's: actor-prior candidates act along their own rollout.
      scores = jnp.mean(jax.vmap(lambda m: combine(m, pessimism))(members), axis=0)
    if intrinsic is not None:
      scores = scores + intrinsic_term(members, latents, intrinsic, gamma)
      if novelty_fn is not None:
        scores = scores + intrinsic.novelty * novelty_fn(params, latents[0], actions)
    return actions, scores, members.reshape((-1,) + members.shape[2:])

  return score_draws


def make_terminal_members(m: ModelSettings, critics: Critics) -> Callable:
  """members(params, z [..., D]) -> [num_values, ...]: each expectile member's V(z), in reward
  units."""
  scale = m.value_scale
  return lambda params, z: scale * critics.apply({'params': params['critics']}, z,
                                                 method=Critics.value)


def make_terminal_value(m: ModelSettings, critics: Critics, pessimism: float = 0.0) -> Callable:
  """value(params, z [..., D]) -> [...]: the expectile members combined (mean - pessimism x
  std), in reward units. It sees the latent alone, never the actions that led to it."""
  members = make_terminal_members(m, critics)
  return lambda params, z: combine(members(params, z), pessimism)


class Expectile:
  """V_m(z_H) from the expectile ensemble; trained by the critic loss (ld_mpc_jax.model.critics)."""
  needs_critics = True
  loss = None  # The critics' term (losses.critic_term) trains it.

  def make_members(self, m: ModelSettings, nets) -> Callable:
    """members(params, latents [K, H+1, D], v_logits [K, H+1, bins]) -> [M, K]."""
    terminal = make_terminal_members(m, nets.critics)
    return lambda params, latents, v_logits: terminal(params, latents[..., -1, :])


class Behaviour:
  """V(z_H) from the sequence objective's value head, regressed on n-step returns."""
  needs_critics = False

  def make_members(self, m: ModelSettings, nets) -> Callable:
    return lambda params, latents, v_logits: two_hot_decode(v_logits[..., -1, :], m.vmin,
                                                            m.vmax)[None]

  @staticmethod
  def loss(m: ModelSettings, nets, target_params, z_ema, action, reward, v_logits):
    """Two-hot cross-entropy of V(z_i), i <= H, against the n-step targets
    sum_{j=i}^{H} gamma^(j-i) r_j + gamma^(H+1-i) V_ema(z_{H+1}), V_ema read by the EMA network
    on the window shifted one step. z_ema [B, H+2, D], action [B, H+1, A], reward [B, H+1],
    v_logits [..., B, H+1, bins] -> (loss [], mean target [])."""
    _, v_tgt_logits = nets.objective.apply({'params': target_params['objective']},
                                           z_ema[:, 1:], action[:, 1:])
    bootstrap = two_hot_decode(v_tgt_logits[:, -1], m.vmin, m.vmax)  # V_ema(z_{H+1}).
    v_target = jax.lax.stop_gradient(window_returns(reward, bootstrap, m.gamma))
    return value_head_loss(v_logits, v_target, m.num_bins, m.vmin, m.vmax), v_target.mean()


def value_head_loss(v_logits: jnp.ndarray, v_target: jnp.ndarray, num_bins: int, vmin: float,
                    vmax: float) -> jnp.ndarray:
  """mean two-hot cross-entropy: v_logits [..., T, bins], v_target [..., T] -> []."""
  return soft_cross_entropy(v_logits, two_hot(v_target, num_bins, vmin, vmax)).mean()


VALUES.register('expectile', Expectile())
VALUES.register('behaviour', Behaviour())


def get(m: ModelSettings):
  """The entry of `critic.value` (ValueError naming the kinds if unknown)."""
  return VALUES.get(m.value)


def make_member_scores(m: ModelSettings, nets, progress_weight: float = 0.0) -> ScoreFn:
  """J under each value member: (params, latents [K, H+1, D], actions [K, H, A]) -> [M, K].

  J_m = sum_i gamma^i r_i + gamma^H V_m(z_H), rewards from the sequence objective (two-hot,
  decoded), V_m from the value kind (module docstring); plus w gamma^H Phi(z_H) with the learned
  progress reward (`plan.progress_weight` = w, ld_mpc_jax.model.progress)."""
  gamma = m.gamma
  members = get(m).make_members(m, nets)

  shaped = progress_weight > 0 and getattr(nets, 'progress', None) is not None

  def score(params, latents, actions):
    r_logits, v_logits = nets.objective.apply({'params': params['objective']}, latents, actions)
    rewards = two_hot_decode(r_logits, m.vmin, m.vmax)  # [K, H]
    scores = discounted_return(rewards[None], members(params, latents, v_logits), gamma)
    if shaped:  # The learned progress reward, as potential-based shaping (model/progress.py).
      scores = scores + progress.bonus(progress_weight, gamma, nets.progress, params, latents)
    return scores

  return score


def make_score(m: ModelSettings, nets, pessimism: float, progress_weight: float = 0.0
               ) -> ScoreFn:
  """J -> [K]: the member scores combined as mean - pessimism x std over the members (the
  planner's: `plan.pessimism`, `plan.progress_weight`)."""
  members = make_member_scores(m, nets, progress_weight)
  return lambda params, latents, actions: combine(members(params, latents, actions), pessimism)


def as_members(scores: jnp.ndarray) -> jnp.ndarray:
  """A score function's output [K] or [M, K] -> [M, K]."""
  return scores[None] if scores.ndim == 1 else scores
