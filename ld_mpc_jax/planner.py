"""Receding-horizon planning in latent space: `make_plan(config) -> plan(params, z, key)`.

One call of `plan`:
  1. samples K - P action sequences [H, A] from the diffusion proposal given z (lax.scan over the
     denoising steps, all candidates batched; optionally energy-guided by the objective);
  2. rolls every candidate out with the latent diffusion dynamics, autoregressively over H
     (outer lax.scan) with a full denoising loop per transition (inner lax.scan); the P
     actor-prior candidates take a_i = Actor(z_hat_i) along their own rollout;
     (the ablation kinds of ld_mpc_jax.models swap in single-step proposals drawn inside the
     rollout, MLP dynamics, or whole-trajectory latent diffusion);
  3. scores each with J = sum_{i<H} gamma^i r_i + gamma^H V(z_H): rewards from the sequence
     objective model, V(z_H) from the expectile value ensemble of z_H alone, pessimistic by
     `plan.pessimism` standard deviations (ld_mpc_jax.critics); with `plan.dynamics_draws` > 1,
     J is averaged over that many rollouts of the same candidates;
  4. returns the first action of the argmax candidate, clipped to [-1, 1], and which kind of
     candidate it was (diffusion proposal or actor prior).
"""

from typing import Callable, Optional

import flax
import jax
import jax.numpy as jnp
import ml_collections

from ld_mpc_jax import diffusion
from ld_mpc_jax.config_checks import validate_config
from ld_mpc_jax.critics import make_terminal_members, objective_settings
from ld_mpc_jax.losses import discounted_return, two_hot_decode
from ld_mpc_jax.models import (ActionProposal, Networks, TrajectoryDynamics, build_networks,
                               dynamics_type, make_transition, normalizes_dynamics, proposal_type,
                               rms_normalize)
from ld_mpc_jax.search import (CANDIDATE_KINDS, Pool, as_members, combine, refine, select,
                               validate_search)

# score_fn(params, latents [K, H+1, D], actions [K, H, A]) -> J [K], or J per member [M, K].
ScoreFn = Callable[[dict, jnp.ndarray, jnp.ndarray], jnp.ndarray]


@flax.struct.dataclass
class PlanOutput:
  """What `plan` returns. K candidates, horizon H, action size A."""
  action: jnp.ndarray  # [A] first action of the best candidate, in [-1, 1].
  sequence: jnp.ndarray  # [H, A] the best candidate (for warm starts and inspection).
  scores: jnp.ndarray  # [K] J of every candidate.
  candidates: jnp.ndarray  # [K, H, A] every candidate action sequence.
  index: jnp.ndarray  # [] the executed candidate (softmax selection: its best elite).
  kind: jnp.ndarray  # [] which kind of candidate won: an index into CANDIDATE_KINDS.
  iteration: jnp.ndarray  # [] after which refinement round it was found (0: the first round).
  departed: jnp.ndarray  # [] bool: the executed sequence is not the actor prior's own.


def make_member_scores(config: ml_collections.ConfigDict, nets: Networks) -> ScoreFn:
  """J under each value-ensemble member: (params, latents [K, H+1, D], actions [K, H, A]) ->
  [M, K], M = `objective.num_values` (expectile ensemble) or 1 (the objective's own behaviour-
  value head). J_m = sum_i gamma^i r_i + gamma^H V_m(z_H), rewards from the sequence objective
  (two-hot, decoded), V_m from member m of the ensemble of z_H alone."""
  m, gamma = config.model, config.gamma
  expectile = objective_settings(config).value == 'expectile'
  members = make_terminal_members(config, nets.critics) if expectile else None

  def score(params, latents, actions):
    r_logits, v_logits = nets.objective.apply({'params': params['objective']}, latents, actions)
    rewards = two_hot_decode(r_logits, m.vmin, m.vmax)  # [K, H]
    if members is None:
      value = two_hot_decode(v_logits[..., -1, :], m.vmin, m.vmax)[None]  # [1, K]
    else:
      value = members(params, latents[..., -1, :])  # [M, K]
    return discounted_return(rewards[None], value, gamma)

  return score


def make_objective_score(config: ml_collections.ConfigDict, nets: Networks) -> ScoreFn:
  """J = sum_i gamma^i r_i + gamma^H V(z_H) -> [K]: the member scores of `make_member_scores`
  combined as mean - `plan.pessimism` x std over the members (search.combine)."""
  members = make_member_scores(config, nets)
  pessimism = config.plan.pessimism
  return lambda params, latents, actions: combine(members(params, latents, actions), pessimism)


def make_step_proposal(config: ml_collections.ConfigDict, nets: Networks) -> Callable:
  """Single-step proposal kinds: returns step_propose(params, zs [N, D], key) -> [N, A].

  'diffusion_step' denoises one action per latent in `plan.action_steps` steps; 'mlp' samples
  the Gaussian policy. Actions are clipped to [-1, 1].
  """
  p, d = config.plan, config.diffusion

  def step_propose(params, zs, key):
    variables = {'params': params['proposal']}
    init_key, sample_key = jax.random.split(key)
    noise = jax.random.normal(init_key, zs.shape[:-1] + (1, config.action_dim))
    if proposal_type(config) == 'mlp':
      mean, log_std = nets.proposal.apply(variables, zs)
      return jnp.clip(mean + jnp.exp(log_std) * noise[..., 0, :], -1.0, 1.0)
    cond = nets.proposal.apply(variables, zs, method=ActionProposal.embed_cond)  # [N, 1, W]
    model_fn = lambda a_t, t: nets.proposal.apply(variables, a_t, t, cond,
                                                  method=ActionProposal.denoise)
    a = diffusion.sample(model_fn, noise, sample_key, p.action_steps, p.action_eta,
                         d.prediction, clip_x0=d.clip_actions)
    return jnp.clip(a[..., 0, :], -1.0, 1.0)

  return step_propose


def make_propose(config: ml_collections.ConfigDict, nets: Networks) -> Callable:
  """Returns propose(params, z [D], key, num, init=None) -> [num, H, A] action sequences.

  Cold start: `plan.action_steps` denoising steps from pure noise at t = 1. Warm start (`init`
  [H, A] given and `plan.warm_start_steps` > 0): `init` is noised to t = `plan.warm_start_t`
  with independent noise per candidate and denoised in `warm_start_steps` steps (SDEdit-style),
  so candidates stay near the previous plan but keep diversity, at a fraction of the cost.

  Energy guidance (`plan.guidance_scale` > 0): at every denoising step the predicted clean
  sequence x0(a_t) is scored by J under a cheap deterministic rollout (`plan.
  guidance_dynamics_steps` DDIM steps per transition) and moved along the gradient of J with
  respect to the noisy sequence a_t: x0 + scale (1 - alpha_bar(t)) g, with g = dJ/da_t scaled
  to unit RMS per candidate (so `scale` is in action units), and guidance fades with the noise.

  Single-step proposal kinds return [num, 1, A]: one action for z (the proposal-alone policy).
  """
  p, d = config.plan, config.diffusion
  h, a = config.horizon, config.action_dim
  if proposal_type(config) != 'diffusion_seq':
    step_propose = make_step_proposal(config, nets)
    return lambda params, z, key, num, init=None: step_propose(
        params, jnp.broadcast_to(z, (num,) + z.shape), key)[:, None]
  guidance = p.get('guidance_scale', 0.0)
  if guidance:
    guide_config = ml_collections.ConfigDict(config.to_dict())
    guide_config.plan.dynamics_steps = p.get('guidance_dynamics_steps', 1)
    guide_config.plan.dynamics_eta = 0.0
    guide_config.plan.num_prior_candidates = 0
    guide_rollout = make_rollout(guide_config, nets)
    score = make_objective_score(config, nets)

  def propose(params, z, key, num, init=None):
    variables = {'params': params['proposal']}
    cond = nets.proposal.apply(variables, z, method=ActionProposal.embed_cond)  # [1, W]
    cond = jnp.broadcast_to(cond, (num,) + cond.shape)
    model_fn = lambda a_t, t: nets.proposal.apply(variables, a_t, t, cond,
                                                  method=ActionProposal.denoise)
    init_key, sample_key, guide_key = jax.random.split(key, 3)
    if guidance:
      unguided = model_fn

      def model_fn(a_t, t):
        def total_return(a_t):
          x0 = jnp.clip(unguided(a_t, t), -d.clip_actions, d.clip_actions)
          _, latents = guide_rollout(params, z, x0, guide_key)
          return score(params, latents, x0).sum(), x0
        grad, x0 = jax.grad(total_return, has_aux=True)(a_t)
        # Unit RMS per candidate: the scale is then in action units, whatever J's scale.
        rms = jnp.sqrt(jnp.mean(grad ** 2, axis=(-2, -1), keepdims=True))
        return x0 + guidance * (1.0 - diffusion.alpha_bar(t)) * grad / (rms + 1e-8)

    noise = jax.random.normal(init_key, (num, h, a))
    if init is None or p.warm_start_steps == 0:
      return diffusion.sample(model_fn, noise, sample_key, p.action_steps, p.action_eta,
                              d.prediction, clip_x0=d.clip_actions)
    x_init = diffusion.q_sample(jnp.broadcast_to(init, (num, h, a)),
                                jnp.full((num,), p.warm_start_t), noise)
    return diffusion.sample(model_fn, x_init, sample_key, p.warm_start_steps, p.action_eta,
                            d.prediction, clip_x0=d.clip_actions, t_start=p.warm_start_t)

  return propose


def shift_sequence(sequence: jnp.ndarray) -> jnp.ndarray:
  """[H, A] plan from the previous step -> [H, A] starting one step later (last one repeated)."""
  return jnp.concatenate([sequence[1:], sequence[-1:]], axis=0)


def make_rollout(config: ml_collections.ConfigDict, nets: Networks) -> Callable:
  """Returns rollout(params, z [D], proposals, key) -> (actions [K, H, A], latents [K, H+1, D]).

  `proposals` is either fixed action sequences [N, H, A], or an int N: then each of the N
  candidates draws a_i from the single-step proposal at its own z_i. The P =
  `plan.num_prior_candidates` actor-prior candidates are appended (K = N + P); they take
  a_i = Actor(z_i) along their own rollout. latents[:, 0] = z. Autoregressive kinds roll out
  with an outer lax.scan over H; 'diffusion_traj' denoises all H latents at once.
  """
  p, d = config.plan, config.diffusion
  num_prior, h = p.num_prior_candidates, config.horizon
  transition = make_transition(config, nets)
  step_propose = (make_step_proposal(config, nets)
                  if proposal_type(config) != 'diffusion_seq' else None)

  def trajectory_rollout(params, z, proposals, key):
    dyn_vars = {'params': params['dynamics']}
    k = proposals.shape[0]
    cond = nets.dynamics.apply(dyn_vars, jnp.broadcast_to(z, (k,) + z.shape), proposals,
                               method=TrajectoryDynamics.embed_cond)
    model_fn = lambda x_t, t: nets.dynamics.apply(dyn_vars, x_t, t, cond,
                                                  method=TrajectoryDynamics.denoise)
    x_init = jax.random.normal(jax.random.fold_in(key, 0), (k, h) + z.shape)
    zs = diffusion.sample(model_fn, x_init, jax.random.fold_in(key, 1), p.dynamics_steps,
                          p.dynamics_eta, d.prediction)
    if normalizes_dynamics(config):
      zs = rms_normalize(zs)
    latents = jnp.concatenate([jnp.broadcast_to(z, (k, 1) + z.shape), zs], axis=1)
    return proposals, latents

  def rollout(params, z, proposals, key):
    if dynamics_type(config) == 'diffusion_traj':
      return trajectory_rollout(params, z, proposals, key)
    sampled = isinstance(proposals, int)
    num = proposals if sampled else proposals.shape[0]
    k = num + num_prior
    xs = jnp.arange(h) if sampled else (jnp.swapaxes(proposals, 0, 1), jnp.arange(h))

    def step(z_cur, inputs):
      i = inputs if sampled else inputs[1]
      step_key = jax.random.fold_in(key, i)
      if sampled:
        a_prop = step_propose(params, z_cur[:num], jax.random.fold_in(step_key, 3))
      else:
        a_prop = inputs[0]
      if num_prior:
        a_pi = nets.actor.apply({'params': params['actor']}, z_cur[num:])
        if p.prior_noise_std > 0:  # Diverse prior candidates; the first one is the actor's own.
          noise = jax.random.normal(jax.random.fold_in(step_key, 2), a_pi.shape)
          noise = noise.at[0].set(0.0)
          a_pi = jnp.clip(a_pi + p.prior_noise_std * noise, -1.0, 1.0)
        a_cur = jnp.concatenate([a_prop, a_pi], axis=0)
      else:
        a_cur = a_prop
      z_next = transition(params, z_cur, a_cur, step_key)
      return z_next, (a_cur, z_next)

    z0 = jnp.broadcast_to(z, (k,) + z.shape)
    _, (acts, zs) = jax.lax.scan(step, z0, xs)
    latents = jnp.concatenate([z0[:, None], jnp.swapaxes(zs, 0, 1)], axis=1)
    return jnp.swapaxes(acts, 0, 1), latents

  return rollout


def make_plan(config: ml_collections.ConfigDict,
              score_fn: Optional[ScoreFn] = None) -> Callable:
  """Builds the jit-compiled planner.

  Args:
    config: an LD-MPC config (see experiments/configs/base.py).
    score_fn: optional replacement for the learned objective,
      (params, latents [K, H+1, D], actions [K, H, A]) -> J [K] or J per member [M, K]; for
      tests and custom objectives.
  Returns:
    plan(params, z [latent_dim], key, prev_sequence=None, action_noise=0.0) -> PlanOutput, one
    jitted pure function. With `plan.warm_start_steps` > 0, passing the previous call's
    `sequence` as `prev_sequence` warm-starts the proposal (and centres the Gaussian set) on it,
    shifted by one step. `action_noise` (a traced scalar, so annealing it never recompiles) is
    the std of Gaussian noise on the executed action: exploration while acting, 0 in evaluation.

  The first round's candidates are the proposal's K - P, then `plan.num_gaussian` broad Gaussian
  sequences N(previous plan or 0, `plan.gaussian_std`^2) clipped to [-1, 1] (TD-MPC2's first
  MPPI samples), then the P actor-prior ones (the first is the actor's own sequence);
  `plan.iterations` refinement rounds follow (ld_mpc_jax.search.refine), whose elites are
  appended to `candidates` and `scores`. Selection: ld_mpc_jax.search.select.
  """
  validate_config(config)
  validate_search(config)
  nets = build_networks(config)
  p = config.plan
  k, num_prior, d = p.num_candidates, p.num_prior_candidates, config.model.latent_dim
  num_gauss, h, a_dim = p.num_gaussian, config.horizon, config.action_dim
  member_fn = make_member_scores(config, nets) if score_fn is None else (
      lambda *args: as_members(score_fn(*args)))
  propose = make_propose(config, nets)
  rollout = make_rollout(config, nets)
  if p.iterations:  # Refined samples are fixed sequences: no actor-prior rollouts among them.
    plain_config = ml_collections.ConfigDict(config.to_dict())
    plain_config.plan.num_prior_candidates = 0
    plain_rollout = make_rollout(plain_config, nets)
  sequence_proposal = proposal_type(config) == 'diffusion_seq'
  draws = p.dynamics_draws
  anchor = k - num_prior + num_gauss if num_prior else -1  # The actor prior's own sequence.
  # Settings read now, not at trace time: a config changed after make_plan changes nothing.
  p = ml_collections.ConfigDict(p.to_dict())

  def score_draws(params, z, proposals, key, roll):
    """(actions [N, H, A], scores [N], members [draws x M, N]): J per draw combined over the
    value members, averaged over `plan.dynamics_draws` rollouts of the same candidates."""
    def one(i):
      acts, lats = roll(params, z, proposals, jax.random.fold_in(key, i))
      return acts, member_fn(params, lats, acts)
    actions, members = one(0)
    if draws == 1:
      return actions, combine(members, p.pessimism), members
    more = jax.lax.map(lambda i: one(i)[1], jnp.arange(1, draws))  # [draws - 1, M, N]
    everything = jnp.concatenate([members[None], more])
    scores = jnp.mean(jax.vmap(lambda m: combine(m, p.pessimism))(everything), axis=0)
    return actions, scores, everything.reshape((-1,) + members.shape[1:])

  def plan(params, z, key, prev_sequence=None, action_noise=0.0) -> PlanOutput:
    if z.shape != (d,):
      raise ValueError(f'plan expects one latent of shape ({d},), got {z.shape}; '
                       'use encode(params, obs) first, and jax.vmap for a batch')
    prop_key, noise_key, dyn_key = jax.random.split(key, 3)
    init = None
    if prev_sequence is not None:
      if prev_sequence.shape != (h, a_dim):
        raise ValueError(f'prev_sequence must have shape ({h}, {a_dim}), '
                         f'got {prev_sequence.shape}')
      init = shift_sequence(prev_sequence)
    if sequence_proposal:
      proposals = propose(params, z, prop_key, k - num_prior, init)
      if p.action_noise_std > 0:
        noise = jax.random.normal(noise_key, proposals.shape)
        proposals = jnp.clip(proposals + p.action_noise_std * noise, -1.0, 1.0)
      if num_gauss:
        centre = jnp.zeros((h, a_dim)) if init is None else init
        eps = jax.random.normal(jax.random.fold_in(noise_key, 1), (num_gauss, h, a_dim))
        proposals = jnp.concatenate(
            [proposals, jnp.clip(centre + p.gaussian_std * eps, -1.0, 1.0)])
    else:  # Single-step proposals are drawn inside the rollout.
      proposals = k - num_prior
    actions, scores, members = score_draws(params, z, proposals, dyn_key, rollout)
    n = actions.shape[0]
    kind = jnp.concatenate([jnp.zeros(k - num_prior, jnp.int32),
                            jnp.full(num_gauss, CANDIDATE_KINDS.index('gaussian'), jnp.int32),
                            jnp.ones(num_prior, jnp.int32)])
    iteration = jnp.zeros(n, jnp.int32)
    if p.iterations:
      def score_samples(samples, key):  # (scores [N], members): as the first round's.
        return score_draws(params, z, samples, key, plain_rollout)[1:]
      pool = refine(score_samples, Pool(actions, scores, members, kind, iteration),
                    jax.random.fold_in(dyn_key, 10_000), p.iterations, p.num_refine,
                    p.num_elites, p.temperature, p.min_std, p.gaussian_std)
      actions = jnp.concatenate([actions, pool.actions])
      scores = jnp.concatenate([scores, pool.scores])
      members = jnp.concatenate([members, pool.members], axis=1)
      kind = jnp.concatenate([kind, pool.kind])
      iteration = jnp.concatenate([iteration, pool.iteration])
    # Elites kept from the first round appear twice: once only in the softmax over elites.
    unique = jnp.concatenate([jnp.ones(n, bool), iteration[n:] > 0]) if p.iterations else None
    sequence, index, departed, _ = select(actions, scores, members, anchor, p.safe_selection,
                                          p.safe_margin, p.selection, p.num_elites,
                                          p.temperature, unique)
    noise = jax.random.normal(jax.random.fold_in(noise_key, 2), (a_dim,))
    action = jnp.clip(sequence[0] + action_noise * noise, -1.0, 1.0)
    return PlanOutput(action=action, sequence=sequence, scores=scores, candidates=actions,
                      index=index, kind=kind[index], iteration=iteration[index],
                      departed=departed)

  return jax.jit(plan)
