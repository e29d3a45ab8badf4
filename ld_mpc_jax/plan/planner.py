"""Receding-horizon planning in latent space: `make_plan(config) -> plan(params, z, key)`.

One call of `plan`:
  1. samples K - P action sequences [H, A] from the diffusion proposal given z (lax.scan over the
     denoising steps, all candidates batched; optionally energy-guided by the objective);
  2. rolls every candidate out with the latent diffusion dynamics, autoregressively over H
     (outer lax.scan) with a full denoising loop per transition (inner lax.scan); the P
     actor-prior candidates take a_i = Actor(z_hat_i) along their own rollout;
     (other kinds, ld_mpc_jax.model.proposals and ld_mpc_jax.model.dynamics, swap in single-step proposals
     drawn inside the rollout, MLP dynamics, or whole-trajectory latent diffusion);
  3. scores each with J = sum_{i<H} gamma^i r_i + gamma^H V(z_H), pessimistic by
     `plan.pessimism` standard deviations over the value members (ld_mpc_jax.model.objective); with
     `plan.dynamics_draws` > 1, J is averaged over that many rollouts of the same candidates;
     while acting, an intrinsic exploration term may be added (objective.Intrinsic);
  4. returns the first action of the argmax candidate, clipped to [-1, 1], and which kind of
     candidate it was (diffusion proposal or actor prior).
"""

import dataclasses
from typing import Callable, Optional

import flax
import jax
import jax.numpy as jnp
import ml_collections

from ld_mpc_jax.ops import build_cache, diffusion
from ld_mpc_jax.model import dynamics, novelty, proposals
from ld_mpc_jax.model.config_checks import check_config
from ld_mpc_jax.model.models import Networks, build_networks
from ld_mpc_jax.model.objective import (Intrinsic, ScoreFn, as_members, make_member_scores,
                                       make_score, make_score_draws)
from ld_mpc_jax.plan.search import (CANDIDATE_KINDS, CANDIDATES, Pool, beats, effective_margin,
                                     first_action_spread, first_round_counts, refine, select,
                                     validate_plan)
from ld_mpc_jax.model.settings import ModelSettings, PlanSettings

__all__ = ['CANDIDATE_KINDS', 'Guard', 'PlanOutput', 'ScoreFn', 'build_plan', 'make_plan',
           'make_propose', 'make_rollout', 'make_member_scores', 'shift_sequence']


@flax.struct.dataclass
class Guard:
  """One episode's state of the fallback to the actor prior (`plan.fallback_drop`), carried from
  one decision to the next; `initial_guard()` at the start of an episode."""
  peak: jnp.ndarray  # [] the highest J of the actor prior's own sequence so far this episode.
  fallen: jnp.ndarray  # [] bool: the planner executes the actor prior's sequence from now on.


def initial_guard() -> Guard:
  """The fallback's state at the start of an episode: no peak yet, not fallen back."""
  return Guard(peak=jnp.asarray(-jnp.inf, jnp.float32), fallen=jnp.asarray(False))


def advance_guard(guard: Guard, prior_score: jnp.ndarray, drop: float,
                  floor: float = 0.0) -> Guard:
  """The state after a decision whose actor prior's own sequence scores `prior_score`: the
  planner falls back (for the rest of the episode) once that score is more than drop x |peak|
  below the episode's peak so far, a peak above `floor`; drop = 0 never falls back."""
  peak = jnp.maximum(guard.peak, prior_score)
  fell = (drop > 0) & (peak > floor) & (prior_score < peak - drop * jnp.abs(peak))
  return Guard(peak=peak, fallen=guard.fallen | fell)


@flax.struct.dataclass
class PlanOutput:
  """What `plan` returns. K candidates, horizon H, action size A."""
  action: jnp.ndarray  # [A] first action of the best candidate, in [-1, 1].
  sequence: jnp.ndarray  # [H, A] the best candidate (for warm starts and inspection).
  scores: jnp.ndarray  # [K] J of every candidate.
  candidates: jnp.ndarray  # [K, H, A] every candidate action sequence.
  index: jnp.ndarray  # [] the executed candidate (softmax selection: its best elite).
  kind: jnp.ndarray  # [] which kind of candidate won: an index into CANDIDATES.names().
  iteration: jnp.ndarray  # [] after which refinement round it was found (0: the first round).
  departed: jnp.ndarray  # [] bool: the executed sequence is not the actor prior's own.
  prior_score: jnp.ndarray  # [] J of the actor prior's own sequence (NaN without one).
  guard: Guard  # The fallback's state after this decision: pass it to the next call.
  # [2] spread of the first actions (search.first_action_spread) of the first round's candidates,
  # and of the proposal's alone (-1 without any): how diverse what the planner tries is.
  # Measured while acting (an `intrinsic` given), else -1: evaluation's program stays as it was.
  spread: jnp.ndarray
  # [] the share of the elites the refinement rounds start from (the first round's
  # `plan.num_elites` best, search.refine) that are the proposal's samples: a refined winner can
  # owe its start to the proposal. Measured while acting with refinement rounds; else -1.
  proposal_elites: jnp.ndarray


def _acting_spread(actions, kinds, intrinsic) -> jnp.ndarray:
  """PlanOutput.spread [2] of a first round's candidates [K, H, A] of kinds [K], measured while
  acting (`intrinsic` given); -1 otherwise, so that the evaluation's program stays as it was."""
  if intrinsic is None:
    return jnp.full(2, -1.0)
  return jnp.stack([first_action_spread(actions),
                    first_action_spread(actions, kinds == CANDIDATES.index('proposal'))])


def make_guide(m: ModelSettings, p: PlanSettings, nets: Networks) -> Optional[Callable]:
  """Energy guidance (`plan.guidance_scale` > 0, else None): guide(params, z [D], key, model_fn)
  -> model_fn whose prediction x0(a_t) [N, H, A] moves along the gradient of J.

  J is scored under a cheap deterministic rollout (`plan.guidance_dynamics_steps` DDIM steps per
  transition); the step is x0 + scale (1 - alpha_bar(t)) g, g = dJ/da_t scaled to unit RMS per
  candidate (so `scale` is in action units), and guidance fades with the noise.
  """
  scale, clip = p.guidance_scale, m.clip_actions
  if not scale:
    return None
  guide_rollout = make_rollout(m, dataclasses.replace(
      p, dynamics_steps=p.guidance_dynamics_steps, dynamics_eta=0.0, num_prior_candidates=0),
                               nets)
  score = make_score(m, nets, p.pessimism, p.progress_weight)

  def guide(params, z, key, unguided):
    def model_fn(a_t, t):
      def total_return(a_t):
        x0 = jnp.clip(unguided(a_t, t), -clip, clip)
        _, latents = guide_rollout(params, z, x0, key)
        return score(params, latents, x0).sum(), x0
      grad, x0 = jax.grad(total_return, has_aux=True)(a_t)
      # Unit RMS per candidate: the scale is then in action units, whatever J's scale.
      rms = jnp.sqrt(jnp.mean(grad ** 2, axis=(-2, -1), keepdims=True))
      return x0 + scale * (1.0 - diffusion.alpha_bar(t)) * grad / (rms + 1e-8)
    return model_fn

  return guide


def make_propose(m: ModelSettings, p: PlanSettings, nets: Networks) -> Callable:
  """Returns propose(params, z [D], key, num, init=None) -> [num, H, A] action sequences: the
  proposal kind's sampler (ld_mpc_jax.model.proposals), energy-guided with `plan.guidance_scale` > 0.

  `init` [H, A] warm-starts sequence kinds (`plan.warm_start_steps`). Single-step proposal
  kinds return [num, 1, A]: one action for z (the proposal-alone policy).
  """
  return proposals.get(m).make_propose(m, p, nets.proposal, make_guide(m, p, nets))


def shift_sequence(sequence: jnp.ndarray) -> jnp.ndarray:
  """[H, A] plan from the previous step -> [H, A] starting one step later (last one repeated)."""
  return jnp.concatenate([sequence[1:], sequence[-1:]], axis=0)


def make_rollout(m: ModelSettings, p: PlanSettings, nets: Networks) -> Callable:
  """Returns rollout(params, z [D], proposals, key) -> (actions [K, H, A], latents [K, H+1, D]).

  `proposals` is either fixed action sequences [N, H, A], or an int N: then each of the N
  candidates draws a_i from the single-step proposal at its own z_i. The P =
  `plan.num_prior_candidates` actor-prior candidates are appended (K = N + P); they take
  a_i = Actor(z_i) along their own rollout. latents[:, 0] = z. One-step dynamics kinds roll out
  with a lax.scan over H (`_scan_rollout`); the others through their entry's `make_rollout`.
  """
  kind = dynamics.get(m)
  if not kind.one_step:
    roll = kind.make_rollout(m, p, nets.dynamics)
    return lambda params, z, actions, key: (actions, roll(params, z, actions, key))
  return _scan_rollout(m, p, nets)


def _scan_rollout(m: ModelSettings, p: PlanSettings, nets: Networks) -> Callable:
  """make_rollout for one-step dynamics kinds: an outer lax.scan over the H transitions."""
  h = m.horizon
  num_prior = p.num_prior_candidates
  transition = dynamics.make_transition(m, nets.dynamics, p.dynamics_steps, p.dynamics_eta)
  proposal = proposals.get(m)
  step_propose = None if proposal.sequence else proposal.make_step(m, p, nets.proposal)

  def prior_actions(params, z_prior, step_key):
    a_pi = nets.actor.apply({'params': params['actor']}, z_prior)
    if p.prior_noise_std > 0:  # Diverse prior candidates; the first one is the actor's own.
      noise = jax.random.normal(jax.random.fold_in(step_key, 2), a_pi.shape)
      noise = noise.at[0].set(0.0)
      a_pi = jnp.clip(a_pi + p.prior_noise_std * noise, -1.0, 1.0)
    return a_pi

  def rollout(params, z, proposals_, key):
    sampled = isinstance(proposals_, int)
    num = proposals_ if sampled else proposals_.shape[0]
    xs = jnp.arange(h) if sampled else (jnp.swapaxes(proposals_, 0, 1), jnp.arange(h))

    def step(z_cur, inputs):
      i = inputs if sampled else inputs[1]
      step_key = jax.random.fold_in(key, i)
      if sampled:
        a_cur = step_propose(params, z_cur[:num], jax.random.fold_in(step_key, 3))
      else:
        a_cur = inputs[0]
      if num_prior:
        a_cur = jnp.concatenate([a_cur, prior_actions(params, z_cur[num:], step_key)], axis=0)
      z_next = transition(params, z_cur, a_cur, step_key)
      return z_next, (a_cur, z_next)

    z0 = jnp.broadcast_to(z, (num + num_prior,) + z.shape)
    _, (acts, zs) = jax.lax.scan(step, z0, xs)
    latents = jnp.concatenate([z0[:, None], jnp.swapaxes(zs, 0, 1)], axis=1)
    return jnp.swapaxes(acts, 0, 1), latents

  return rollout


def _make_first_round(m: ModelSettings, p: PlanSettings, nets: Networks) -> Callable:
  """first(params, z, prop_key, noise_key, init) -> the first round's proposals: the sequences
  [N, H, A] of the kinds in `plan.first_round` (ld_mpc_jax.plan.search.CANDIDATES; by default the
  proposal's K - P, then `plan.num_gaussian` broad Gaussian ones), or for single-step proposal
  kinds the int K - P (drawn inside the rollout)."""
  if not proposals.get(m).sequence:
    num = p.num_candidates - p.num_prior_candidates
    return lambda params, z, prop_key, noise_key, init: num
  propose = make_propose(m, p, nets)
  draws = [CANDIDATES.get(name).make(m, p, nets, propose)
           for name, num in first_round_counts(p) if num]

  def first(params, z, prop_key, noise_key, init):
    if not draws:  # Only the actor prior's candidates (num_candidates == num_prior_candidates).
      return jnp.zeros((0, m.horizon, m.action_dim))
    return jnp.concatenate([draw(params, z, prop_key, noise_key, init) for draw in draws])

  return first


def _first_kinds(p: PlanSettings) -> jnp.ndarray:
  """[N + P] int32 candidate kinds of the first round, in the candidates' order."""
  return jnp.concatenate(
      [jnp.full(num, CANDIDATES.index(name), jnp.int32) for name, num in first_round_counts(p)]
      + [jnp.full(p.num_prior_candidates, CANDIDATES.index('actor_prior'), jnp.int32)])


def _make_refine(p: PlanSettings, score_draws: Callable, plain_rollout: Callable
                 ) -> Optional[Callable]:
  """`plan.iterations` refinement rounds (ld_mpc_jax.plan.search.refine), or None without:
  refine(params, z, key, first: Pool, intrinsic) -> the first round's pool with the rounds'
  elites appended, `unique` [K'] bool (elites kept from the first round appear twice: once
  only in the softmax over elites) and the kinds [E] of the elites the rounds started from."""
  if not p.iterations:
    return None
  def refine_pool(params, z, key, first, intrinsic):
    def score_samples(samples, k):  # (scores [N], members): as the first round's.
      return score_draws(params, z, samples, k, plain_rollout, intrinsic)[1:]
    pool, start = refine(score_samples, first, jax.random.fold_in(key, 10_000), p.iterations,
                         p.num_refine, p.num_elites, p.temperature, p.min_std, p.gaussian_std)
    merged = Pool(*(jnp.concatenate([x, y], axis=1 if name == 'members' else 0)
                    for name, x, y in zip(Pool._fields, first, pool)))
    n = first.scores.shape[0]
    unique = jnp.concatenate([jnp.ones(n, bool), pool.iteration > 0])
    return merged, unique, start

  return refine_pool


def _fall_back(p, pool: Pool, anchor: int, sequence, index, departed, guard: Optional[Guard],
               active: bool):
  """(sequence, index, departed, prior_score, guard) after the fallback (`plan.fallback_drop`,
  `active` with safe selection: PlanSettings.gates): the guard advanced by the actor prior's score,
  and once it has fallen, the actor prior's own sequence whatever won. Without an actor prior
  among the candidates: unchanged, prior_score NaN."""
  guard = initial_guard() if guard is None else guard
  if anchor < 0:
    return sequence, index, departed, jnp.asarray(jnp.nan, jnp.float32), guard
  prior_score = pool.scores[anchor]
  guard = advance_guard(guard, prior_score, p.fallback_drop if active else 0.0, p.fallback_floor)
  if active:
    sequence = jnp.where(guard.fallen, pool.actions[anchor], sequence)
    index = jnp.where(guard.fallen, anchor, index)
    departed = departed & ~guard.fallen
  return sequence, index, departed, prior_score, guard


def _warm_start(prev_sequence: Optional[jnp.ndarray], h: int, a_dim: int
                ) -> Optional[jnp.ndarray]:
  """The previous plan [H, A] shifted one step (shift_sequence), or None without one."""
  if prev_sequence is None:
    return None
  if prev_sequence.shape != (h, a_dim):
    raise ValueError(f'prev_sequence must have shape ({h}, {a_dim}), got {prev_sequence.shape}')
  return shift_sequence(prev_sequence)


def make_plan(config: ml_collections.ConfigDict,
              score_fn: Optional[ScoreFn] = None) -> Callable:
  """Builds the jit-compiled planner of a config: `build_plan` of its model's and planner's
  settings (ld_mpc_jax.model.settings), after the config's checks."""
  check_config(config)  # build_plan checks the planner's settings.
  return build_plan(ModelSettings.from_config(config), PlanSettings.from_config(config),
                    score_fn)


def build_plan(model: ModelSettings, plan: PlanSettings,
               score_fn: Optional[ScoreFn] = None) -> Callable:
  """Builds the jit-compiled planner.

  Args:
    model: the networks' settings (ModelSettings.from_config(config)).
    plan: the planner's (PlanSettings.from_config(config), or a dataclasses.replace of them).
    score_fn: optional replacement for the learned objective,
      (params, latents [K, H+1, D], actions [K, H, A]) -> J [K] or J per member [M, K]; for
      tests and custom objectives.
  Returns:
    plan(params, z [latent_dim], key, prev_sequence=None, action_noise=0.0, guard=None,
    intrinsic=None) -> PlanOutput, one jitted pure function, the same one for equal settings
    in this process (ld_mpc_jax.ops.build_cache; a `score_fn` always builds a new one). With
    `plan.warm_start_steps` > 0, passing the previous call's `sequence` as `prev_sequence`
    warm-starts the proposal (and centres the Gaussian set) on it, shifted by one step. `action_noise` (a traced scalar, so annealing it never recompiles) is
    the std of Gaussian noise on the executed action: exploration while acting, 0 in evaluation.
    `guard` is the previous call's `PlanOutput.guard` in the same episode (None at its start):
    with `plan.fallback_drop` > 0 the planner executes the actor prior's own sequence once the
    objective's value of the state has fallen that far below the episode's peak, a peak above
    `plan.fallback_floor` (`Guard`). `intrinsic` (acting only; an objective.Intrinsic of
    traced scalars, so annealing it never recompiles) adds the acting planner's exploration
    term to J: optimism over the value members and the dynamics draws' disagreement.

  The first round holds the kinds of `plan.first_round` (search.CANDIDATES: by default the
  proposal's K - P, then `plan.num_gaussian` broad Gaussian sequences, TD-MPC2's first MPPI
  samples), then the P actor-prior ones (the first is the actor's own sequence);
  `plan.iterations` refinement rounds follow (ld_mpc_jax.plan.search.refine), whose elites are
  appended to `candidates` and `scores`. Selection: ld_mpc_jax.plan.search.select.
  """
  validate_plan(plan, model)
  if score_fn is None:  # One traced planner per settings value in a process (build_cache).
    return _cached_plan(model, plan)
  return _build_plan(model, plan, score_fn)


@build_cache.by_settings  # Traced once per settings value in a process.
def _cached_plan(model: ModelSettings, plan: PlanSettings) -> Callable:
  return _build_plan(model, plan, None)


def _novelty_fn(m: ModelSettings, nets: Networks) -> Optional[ScoreFn]:
  """The learned exploration value's bonus in the acting J (ld_mpc_jax.model.novelty), or None
  for a model without it."""
  if nets.novelty is None:
    return None
  return lambda params, lats, acts: novelty.bonus(nets.novelty, params, lats, acts, m.gamma)


def _build_plan(m: ModelSettings, p: PlanSettings, score_fn: Optional[ScoreFn]) -> Callable:
  nets = build_networks(m)
  d, h, a_dim = m.latent_dim, m.horizon, m.action_dim
  member_fn = make_member_scores(m, nets, p.progress_weight) if score_fn is None else (
      lambda *args: as_members(score_fn(*args)))
  first_round = _make_first_round(m, p, nets)
  rollout = make_rollout(m, p, nets)
  score_draws = make_score_draws(member_fn, p.dynamics_draws, p.pessimism, m.gamma,
                                 _novelty_fn(m, nets))
  confirm_draws = make_score_draws(member_fn, p.confirm_draws, p.pessimism, m.gamma)
  # Fixed sequences, no actor-prior rollouts among them: refined samples, and the pair that
  # plan.safe_confirm rolls again.
  plain_rollout = make_rollout(m, dataclasses.replace(p, num_prior_candidates=0), nets)
  refine_pool = _make_refine(p, score_draws, plain_rollout)
  kinds, num_first = _first_kinds(p), sum(n for _, n in first_round_counts(p))
  anchor = num_first if p.num_prior_candidates else -1  # The actor prior's own sequence.
  margin = effective_margin(p)  # plan.safe_margin, scaled by K if asked.
  confirm_margin = p.safe_margin if p.confirm_margin < 0 else p.confirm_margin
  confirm, fallback = p.gates  # Inert without plan.safe_selection.

  def plan(params, z, key, prev_sequence=None, action_noise=0.0, guard=None,
           intrinsic: Optional[Intrinsic] = None) -> PlanOutput:
    if z.shape != (d,):
      raise ValueError(f'plan expects one latent of shape ({d},), got {z.shape}; '
                       'use encode(params, obs) first, and jax.vmap for a batch')
    prop_key, noise_key, dyn_key = jax.random.split(key, 3)
    init = _warm_start(prev_sequence, h, a_dim)
    proposals_ = first_round(params, z, prop_key, noise_key, init)
    actions, scores, members = score_draws(params, z, proposals_, dyn_key, rollout, intrinsic)
    pool = Pool(actions, scores, members, kinds,
                jnp.zeros(actions.shape[0], jnp.int32))
    spread, proposal_elites = _acting_spread(actions, kinds, intrinsic), jnp.asarray(-1.0)
    unique = None
    if refine_pool is not None:
      pool, unique, start = refine_pool(params, z, dyn_key, pool, intrinsic)
      if intrinsic is not None:  # Measured while acting.
        proposal_elites = jnp.mean(start == CANDIDATES.index('proposal'))
    sequence, index, departed, _ = select(pool.actions, pool.scores, pool.members, anchor,
                                          p.safe_selection, margin, p.selection,
                                          p.num_elites, p.temperature, unique)
    if confirm:  # The departure again, on fresh dynamics draws.
      pair = jnp.stack([sequence, pool.actions[anchor]])
      _, fresh, fresh_members = confirm_draws(
          params, z, pair, jax.random.fold_in(dyn_key, 20_000), plain_rollout, intrinsic)
      keep = departed & beats(fresh, fresh_members, 0, 1, confirm_margin)
      sequence = jnp.where(keep, sequence, pool.actions[anchor])
      index, departed = jnp.where(keep, index, anchor), keep
    sequence, index, departed, prior_score, guard = _fall_back(
        p, pool, anchor, sequence, index, departed, guard, fallback)
    noise = jax.random.normal(jax.random.fold_in(noise_key, 2), (a_dim,))
    action = jnp.clip(sequence[0] + action_noise * noise, -1.0, 1.0)
    return PlanOutput(action=action, sequence=sequence, scores=pool.scores,
                      candidates=pool.actions, index=index, kind=pool.kind[index],
                      iteration=pool.iteration[index], departed=departed,
                      prior_score=prior_score, guard=guard, spread=spread,
                      proposal_elites=proposal_elites)

  return jax.jit(plan)
