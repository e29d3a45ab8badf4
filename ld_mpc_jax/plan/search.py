"""Search and selection inside `plan`: refinement around the elites, and safe selection.

Pure functions of arrays, used by ld_mpc_jax.plan.planner (which builds the candidates and scores
them). Scores come per *member*: J under each member of the value ensemble (and each dynamics
draw), an array [M, K]; a candidate's score is mean - pessimism x std over the members.

Refinement (`plan.iterations` > 0) follows TD-MPC2's MPPI update (Hansen et al. 2024, planning
in `tdmpc2.py`): keep the `plan.num_elites` best sequences, fit a mean and a std to them with
softmax weights exp(temperature (J - max J)), draw `plan.num_refine` new sequences from that
Gaussian (std at least `plan.min_std`), score them, keep the best of elites and new samples, and
repeat. The std shrinks as the elites agree: the search anneals itself.

Safe selection (`plan.safe_selection`): the actor prior's own sequence is always a candidate, and
the planner departs from it only when the best candidate's score exceeds the actor's by more than
`plan.safe_margin` times the spread of their difference over the members (a paired comparison:
both are scored by the same ensemble members and dynamics draws). In the spirit of safe policy
improvement (SPIBB, Laroche et al. 2019: keep the baseline's action where the data cannot
support a change) and of uncertainty-penalised planning (MOPO, FOWM). With
`plan.safe_margin_scaling='expected_max'` the margin grows with the number of candidates scored:
the winner is the maximum of n noisy scores, so its expected optimism is about E[max of n
standard normals] (`expected_max(n)`, about sqrt(2 ln n)) score-noise units, and the threshold is
safe_margin x expected_max(n) x the spread (`effective_margin`).

Confirmation (`plan.safe_confirm`, with safe selection): a departure must also pass on a second,
independent rollout of the executed sequence and the actor prior's (`beats` on fresh scores).
The winner was chosen on the first rollout's draws, so its score there carries the selection's
optimism; scored again on fresh draws it does not (the double estimator of van Hasselt 2010, "Double Q-learning":
select with one estimate, evaluate with another). The second test uses `plan.confirm_margin`,
or where that is negative `plan.safe_margin` unscaled, as no candidate was selected on it. With
`plan.confirm_draws` = n > 1 the pair is rolled out n times: the gain is its mean over the
rollouts and the spread is taken over members and rollouts together, so the dynamics'
draw-to-draw noise, shared by the members, counts too.
"""

import dataclasses
import math
from typing import Callable, NamedTuple, Optional, Tuple

import jax
import jax.numpy as jnp
import numpy as np

from ld_mpc_jax.model import proposals
from ld_mpc_jax.model.settings import ModelSettings, PlanSettings
from ld_mpc_jax.ops.registry import Registry


@dataclasses.dataclass(frozen=True)
class CandidateKind:
  """One kind of candidate of `plan`.

  First-round kinds (named in `plan.first_round`) carry `count(plan)` (how many sequences, from
  the PlanSettings) and `make(model, plan, nets, propose)` -> draw(params, z [D], prop_key,
  noise_key, init) -> [n, H, A] sequences in [-1, 1] (`model` and `plan` are the
  ld_mpc_jax.model.settings, `propose` the planner's proposal sampler, `init` the previous plan
  shifted, or None; derive your own keys with jax.random.fold_in). The actor prior's rollouts
  and the refinement rounds are built by the planner itself (count and make None). A kind whose
  count is above 0 must be named in `plan.first_round` (so read the count from a plan field).
  """
  description: str
  count: Optional[Callable[[PlanSettings], int]] = None
  make: Optional[Callable] = None


def _proposal_count(plan: PlanSettings) -> int:
  return plan.num_candidates - plan.num_prior_candidates


def _proposal_draws(model: ModelSettings, plan: PlanSettings, nets, propose: Callable
                    ) -> Callable:
  """The proposal's K - P sequences, with `plan.action_noise_std` Gaussian noise (clipped)."""
  num, noise_std = _proposal_count(plan), plan.action_noise_std

  def draw(params, z, prop_key, noise_key, init):
    out = propose(params, z, prop_key, num, init)
    if noise_std > 0:
      out = jnp.clip(out + noise_std * jax.random.normal(noise_key, out.shape), -1.0, 1.0)
    return out
  return draw


def _gaussian_draws(model: ModelSettings, plan: PlanSettings, nets, propose: Callable
                    ) -> Callable:
  """`plan.num_gaussian` sequences N(previous plan or 0, `plan.gaussian_std`^2), clipped."""
  num, std = plan.num_gaussian, plan.gaussian_std
  shape = (num, model.horizon, model.action_dim)

  def draw(params, z, prop_key, noise_key, init):
    centre = jnp.zeros(shape[1:]) if init is None else init
    eps = jax.random.normal(jax.random.fold_in(noise_key, 1), shape)
    return jnp.clip(centre + std * eps, -1.0, 1.0)
  return draw


# Where a candidate of one plan came from. The index of a name is the id plans report
# (PlanOutput.kind) and online/diagnostics count by, so the order is fixed and new kinds go at
# the end. A plan's first round holds the kinds of `plan.first_round` in that order, then the
# actor prior's (its first one is the actor's own sequence), then the refined samples.
CANDIDATES = Registry('candidate kind', 'config.plan.first_round')
CANDIDATES.register('proposal', CandidateKind("the proposal's samples", _proposal_count,
                                              _proposal_draws))
CANDIDATES.register('actor_prior', CandidateKind(
    'actor-prior rollouts: a_i = Actor(z_i) along their own rollout'))
CANDIDATES.register('gaussian', CandidateKind(
    'broad Gaussian sequences around the previous plan (or 0)',
    lambda plan: plan.num_gaussian, _gaussian_draws))
CANDIDATES.register('refined', CandidateKind('samples of a refinement round around the elites'))
CANDIDATE_KINDS = CANDIDATES.names()  # The built-in kinds; CANDIDATES.names() has any added.


def first_round_counts(plan: PlanSettings) -> Tuple[Tuple[str, int], ...]:
  """(kind, how many) of the first round's drawn kinds, in `plan.first_round` order (the P
  actor-prior candidates follow them)."""
  return tuple((name, int(CANDIDATES.get(name).count(plan))) for name in plan.first_round)


SELECTIONS = ('argmax', 'softmax')
MARGIN_SCALINGS = ('none', 'expected_max')


def first_action_spread(actions: jnp.ndarray, mask: Optional[jnp.ndarray] = None) -> jnp.ndarray:
  """actions [K, H, A] -> []: the std over the candidates of their first action (the one
  executed), averaged over the action dimensions: how diverse the candidates are. Only those
  where `mask` [K] is True; -1 where that leaves none."""
  first = actions[:, 0]
  w = (jnp.ones(first.shape[:1]) if mask is None else mask.astype(first.dtype))[:, None]
  n = jnp.maximum(jnp.sum(w), 1.0)
  mean = jnp.sum(w * first, axis=0) / n
  std = jnp.sqrt(jnp.sum(w * (first - mean) ** 2, axis=0) / n)
  return jnp.where(jnp.sum(w) > 0, jnp.mean(std), -1.0)


def elite_moments(actions: jnp.ndarray, scores: jnp.ndarray, temperature: float,
                  min_std: float, max_std: float) -> Tuple[jnp.ndarray, jnp.ndarray]:
  """Softmax-weighted mean and std of elites: actions [E, H, A], scores [E] -> [H, A] x 2.

  Weights exp(temperature (J - max J)), normalised (TD-MPC2's MPPI); std clipped to
  [min_std, max_std].
  """
  w = jax.nn.softmax(temperature * (scores - jnp.max(scores)))[:, None, None]
  mean = jnp.sum(w * actions, axis=0)
  std = jnp.sqrt(jnp.sum(w * (actions - mean) ** 2, axis=0))
  return mean, jnp.clip(std, min_std, max_std)


class Pool(NamedTuple):
  """The elites: E sequences with their scores and where they came from."""
  actions: jnp.ndarray  # [E, H, A]
  scores: jnp.ndarray  # [E]
  members: jnp.ndarray  # [M, E]
  kind: jnp.ndarray  # [E] int32, index into CANDIDATES.names()
  iteration: jnp.ndarray  # [E] int32: 0 for the first round, i for the i-th refinement


def top_pool(pool: Pool, num: int) -> Pool:
  """The `num` best of a pool (by score)."""
  _, idx = jax.lax.top_k(pool.scores, num)
  return Pool(pool.actions[idx], pool.scores[idx], pool.members[:, idx], pool.kind[idx],
              pool.iteration[idx])


def refine(score_fn: Callable, first: Pool, key: jax.Array, iterations: int, num_samples: int,
           num_elites: int, temperature: float, min_std: float, max_std: float
           ) -> Tuple[Pool, jnp.ndarray]:
  """MPPI-style refinement: returns the final elites (E = num_elites) with their provenance,
  and the kinds [E] of the first round's elites it started from.

  score_fn(actions [N, H, A], key) -> (scores [N], member scores [M, N]), scored as the first
  round's candidates were (the same draws and pessimism). `first` is the first round's scored
  candidates. Each of `iterations` rounds (lax.scan) draws `num_samples` sequences from the
  elites' softmax-weighted Gaussian, clipped to [-1, 1], and keeps the best `num_elites` of
  elites and samples.
  """
  pool = top_pool(first, num_elites)

  def step(pool, i):
    mean, std = elite_moments(pool.actions, pool.scores, temperature, min_std, max_std)
    k_draw, k_score = jax.random.split(jax.random.fold_in(key, i))
    eps = jax.random.normal(k_draw, (num_samples,) + mean.shape)
    samples = jnp.clip(mean + std * eps, -1.0, 1.0)
    scores, members = score_fn(samples, k_score)
    new = Pool(samples, scores, members,
               jnp.full((num_samples,), CANDIDATES.index('refined'), jnp.int32),
               jnp.full((num_samples,), i, jnp.int32))
    merged = Pool(*(jnp.concatenate([x, y], axis=1 if name == 'members' else 0)
                    for name, x, y in zip(Pool._fields, pool, new)))
    return top_pool(merged, num_elites), None

  start = pool.kind
  pool, _ = jax.lax.scan(step, pool, jnp.arange(1, iterations + 1))
  return pool, start


def select(actions: jnp.ndarray, scores: jnp.ndarray, members: jnp.ndarray, anchor: int,
           safe: bool, margin: float, selection: str, num_elites: int, temperature: float,
           unique: Optional[jnp.ndarray] = None
           ) -> Tuple[jnp.ndarray, jnp.ndarray, jnp.ndarray, jnp.ndarray]:
  """Chooses what to execute among K scored candidates.

  actions [K, H, A], scores [K], members [M, K]; anchor: the index of the actor prior's own
  sequence (or -1: none). Returns (sequence [H, A], index [], departed [] bool, weights [K]):
  - 'argmax': the best candidate; 'softmax': the softmax-weighted mean of the `num_elites` best
    (weights exp(temperature (J - max J)), MPPI), `index` its best elite; `unique` [K] bool
    leaves repeated candidates out of the softmax;
  - with `safe`, the anchor's sequence unless the best candidate beats the anchor by more than
    margin x std over members of (J_best - J_anchor); ties keep the anchor. Under 'softmax' the
    gain is the elites' softmax-weighted J (per member) minus the anchor's, a proxy for the J
    of the weighted mean sequence that is executed (which is not scored): the elites together
    must beat the anchor, not only the best one.
  `departed` is whether the executed sequence is not the anchor's (always True without one).
  """
  best = jnp.argmax(scores)
  if selection == 'softmax':
    e = min(num_elites, scores.shape[0])
    masked = scores if unique is None else jnp.where(unique, scores, -jnp.inf)
    top_scores, top_idx = jax.lax.top_k(masked, e)
    w_top = jax.nn.softmax(temperature * (top_scores - top_scores[0]))
    weights = jnp.zeros_like(scores).at[top_idx].set(w_top)
    chosen = jnp.sum(weights[:, None, None] * actions, axis=0)
  else:
    weights = jax.nn.one_hot(best, scores.shape[0], dtype=scores.dtype)
    chosen = actions[best]
  if anchor < 0:
    return chosen, best, jnp.asarray(True), weights
  if safe and selection == 'softmax':  # The weighted elites' gain over the anchor, as executed.
    diff = jnp.sum(members * weights, axis=-1) - members[:, anchor]  # Exact sums on GPU too.
    depart = jnp.sum(scores * weights) - scores[anchor] > margin * jnp.std(diff)
  elif safe:
    depart = beats(scores, members, best, anchor, margin)
  else:
    depart = best != anchor if selection == 'argmax' else jnp.asarray(True)
  sequence = jnp.where(depart, chosen, actions[anchor])
  weights = jnp.where(depart, weights, jax.nn.one_hot(anchor, scores.shape[0],
                                                      dtype=scores.dtype))
  return sequence, jnp.where(depart, best, anchor), depart, weights


def beats(scores: jnp.ndarray, members: jnp.ndarray, i, j, margin: float) -> jnp.ndarray:
  """The safe gate: candidate i's score beats candidate j's by more than margin x the std over
  members of their difference (scores [K], members [M, K]; a paired comparison)."""
  return scores[i] - scores[j] > margin * jnp.std(members[:, i] - members[:, j])


def expected_max(n: int) -> float:
  """E[max of n independent standard normals]: 0 for n = 1, 1/sqrt(pi) for n = 2, about
  sqrt(2 ln n) for large n. Numerical integral of x n phi(x) Phi(x)^(n-1) (build time, NumPy)."""
  if n < 1:
    raise ValueError(f'expected_max needs n >= 1, got {n}')
  from scipy import integrate, special  # pylint: disable=g-import-not-at-top
  x = np.linspace(-12.0, 12.0, 24_001)
  pdf = np.exp(-0.5 * x * x) / math.sqrt(2.0 * math.pi)
  return float(integrate.trapezoid(x * n * pdf * special.ndtr(x) ** (n - 1), x))


def num_scored(plan: PlanSettings) -> int:
  """Candidates `plan` scores in one call: the first round (the actor prior's included) and
  `plan.num_refine` per refinement round."""
  first = sum(n for _, n in first_round_counts(plan)) + plan.num_prior_candidates
  return first + plan.iterations * plan.num_refine


def effective_margin(plan: PlanSettings) -> float:
  """The safe-selection margin used by `plan`: `plan.safe_margin`, times
  expected_max(candidates scored) under `plan.safe_margin_scaling='expected_max'`."""
  if plan.safe_margin_scaling == 'expected_max':
    return plan.safe_margin * expected_max(num_scored(plan))
  return float(plan.safe_margin)


def check_first_round(plan: PlanSettings) -> Tuple[Tuple[str, int], ...]:
  """`plan.first_round`: registered kinds that draw sequences, each once, the proposal among
  them; -> first_round_counts(plan). One-line ValueErrors (validate_plan)."""
  names = tuple(plan.first_round)
  drawn = tuple(n for n in CANDIDATES.names() if CANDIDATES.get(n).make is not None)
  for name in names:
    if CANDIDATES.check(name) not in drawn:
      raise ValueError(f'config.plan.first_round: {name!r} is not drawn in the first round; use '
                       f'{", ".join(map(repr, drawn))}')
  if len(set(names)) != len(names) or 'proposal' not in names:
    raise ValueError(f"config.plan.first_round must name each kind once, 'proposal' among them, "
                     f'got {names}')
  for name in drawn:  # A kind given a count but left out of the first round would be ignored.
    if name not in names and CANDIDATES.get(name).count(plan) > 0:
      raise ValueError(f'config.plan.first_round leaves out {name!r}, which its settings give '
                       f'{CANDIDATES.get(name).count(plan)} candidates: add it, or set its '
                       'count to 0')
  return first_round_counts(plan)


def validate_plan(plan: PlanSettings, model: ModelSettings) -> None:
  """One-line ValueErrors for the planner's settings (`config.plan`) with `model`'s kinds: the
  samplers', the candidates', the search's and the selection's."""
  for name in ('action_eta', 'dynamics_eta'):
    if not 0.0 <= getattr(plan, name) <= 1.0:
      raise ValueError(f'config.plan.{name} must be in [0, 1], got {getattr(plan, name)}')
  if not 0 <= plan.num_prior_candidates <= plan.num_candidates:
    raise ValueError(f'config.plan.num_prior_candidates must be in [0, num_candidates='
                     f'{plan.num_candidates}], got {plan.num_prior_candidates}')
  for name in ('prior_noise_std', 'action_noise_std'):
    if getattr(plan, name) < 0:
      raise ValueError(f'config.plan.{name} must be >= 0, got {getattr(plan, name)}')
  if not isinstance(plan.warm_start_steps, int) or plan.warm_start_steps < 0:
    raise ValueError(f'config.plan.warm_start_steps must be an integer >= 0, '
                     f'got {plan.warm_start_steps!r}')
  if not 0.0 < plan.warm_start_t <= 1.0:
    raise ValueError(f'config.plan.warm_start_t must be in (0, 1], got {plan.warm_start_t}')
  if not 0.0 <= plan.latent_filter < 1.0:
    raise ValueError(f'config.plan.latent_filter must be in [0, 1), got {plan.latent_filter}')
  if plan.progress_weight < 0:
    raise ValueError(f'config.plan.progress_weight must be >= 0, got {plan.progress_weight}')
  if plan.progress_weight > 0 and not model.progress:  # ld_mpc_jax.model.progress
    raise ValueError('config.plan.progress_weight > 0 needs the progress head: set '
                     'config.loss.w_progress > 0 (its loss weight) too')
  if plan.selection not in SELECTIONS:
    raise ValueError(f'config.plan.selection must be one of {SELECTIONS}, '
                     f'got {plan.selection!r}')
  for name in ('num_gaussian', 'iterations'):
    if getattr(plan, name) < 0:
      raise ValueError(f'config.plan.{name} must be >= 0, got {getattr(plan, name)}')
  if plan.iterations and (plan.num_refine < 1 or plan.num_elites < 1):
    raise ValueError('config.plan.num_refine and config.plan.num_elites must be >= 1 when '
                     f'config.plan.iterations > 0, got {plan.num_refine} and '
                     f'{plan.num_elites}')
  counts = check_first_round(plan)
  num_first = sum(n for _, n in counts) + plan.num_prior_candidates
  if plan.iterations and plan.num_elites > num_first:
    raise ValueError(f'config.plan.num_elites ({plan.num_elites}) exceeds the first round\'s '
                     f'candidates ({num_first})')
  if plan.min_std <= 0 or plan.gaussian_std <= 0:
    raise ValueError('config.plan.min_std and config.plan.gaussian_std must be > 0')
  if plan.safe_selection and plan.num_prior_candidates < 1:
    raise ValueError('config.plan.safe_selection needs the actor prior\'s own sequence as a '
                     'candidate: set config.plan.num_prior_candidates >= 1')
  if plan.safe_margin < 0:
    raise ValueError(f'config.plan.safe_margin must be >= 0, got {plan.safe_margin}')
  if plan.confirm_draws < 1:
    raise ValueError(f'config.plan.confirm_draws must be >= 1, got {plan.confirm_draws}')
  if not 0.0 <= plan.fallback_drop < 1.0:
    raise ValueError(f'config.plan.fallback_drop must be in [0, 1), got {plan.fallback_drop}')
  if plan.safe_margin_scaling not in MARGIN_SCALINGS:
    raise ValueError(f'config.plan.safe_margin_scaling must be one of {MARGIN_SCALINGS}, '
                     f'got {plan.safe_margin_scaling!r}')
  others = any(n for name, n in counts if name != 'proposal')
  if (others or plan.iterations) and not proposals.PROPOSALS.get(model.proposal_type).sequence:
    raise ValueError('config.plan.num_gaussian (any first-round kind but the proposal) and '
                     'config.plan.iterations need whole action sequences, not proposal_type '
                     f'{model.proposal_type!r}')
