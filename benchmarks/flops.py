"""FLOPs of one `plan` call: an analytic count from the model's and the planner's settings
(ModelSettings, PlanSettings) and a trip-count-corrected XLA count.

Counting convention: a multiply-add is 2 FLOPs, a bias add 1 FLOP per output element. The
analytic (hand) count covers every matrix product of the models (dense layers, attention scores
and mixing) and their bias adds; it leaves out element-wise work (LayerNorm, GELU, softmax, the
sampler's update, random numbers), which XLA does count. That difference is a few percent at
widths >= 32 and shrinks with width.

XLA's `compiled.cost_analysis()` counts the body of a `lax.scan` (a while loop) once, not once
per iteration, so the cost of the whole compiled `plan` misses (steps - 1) of every denoising
loop. `xla_plan_flops` corrects it: it lowers each loop body on its own, with the batch shape it
sees inside `plan`, and adds the missing iterations:

  total = C(plan) + (S_a - 1) C(proposal step) + (H - 1) C(transition with 1 dynamics step)
          + H (S_d - 1) C(dynamics step)

where C(plan) itself holds the non-scanned parts plus every loop body once.
"""

import dataclasses
from typing import Callable

import jax
import jax.numpy as jnp

from ld_mpc_jax.ops import diffusion
from ld_mpc_jax.model.models import (ActionProposal, LatentDynamics, build_networks,
                                     init_params_from)
from ld_mpc_jax.model.settings import ModelSettings, PlanSettings


# ---------------------------------------------------------------------------------------------
# Analytic count.


def dense_flops(n_in: int, n_out: int, rows: int = 1, bias: bool = True) -> int:
  """FLOPs of a Dense layer [rows, n_in] -> [rows, n_out]: 2 n_in n_out (+ n_out bias) per row."""
  return rows * (2 * n_in * n_out + (n_out if bias else 0))


def attention_flops(length: int, width: int, rows: int = 1, queries: int | None = None) -> int:
  """Scores Q K^T and mixing softmax(.) V, `queries` (default all) tokens attending to `length`.

  Summed over heads, each of the two products is L_q x L x W multiply-adds, independent of the
  number of heads: 2 x 2 L_q L W per sequence.
  """
  queries = length if queries is None else queries
  return rows * 2 * (2 * queries * length * width)


def transformer_block_flops(length: int, width: int, mlp_ratio: int, rows: int = 1,
                            outputs: int | None = None) -> int:
  """One pre-LN block on [rows, L, W]: QKV + output projections, attention, 2-layer MLP.

  With `outputs` < L (the last block of a Transformer called with `outputs`), Q, K and V are
  still projected for all L tokens (one fused matmul), and attention, the output projection and
  the MLP run on the `outputs` tokens only.
  """
  outputs = length if outputs is None else outputs
  projections = (3 * dense_flops(width, width, rows * length)
                 + dense_flops(width, width, rows * outputs))
  mlp = (dense_flops(width, mlp_ratio * width, rows * outputs)
         + dense_flops(mlp_ratio * width, width, rows * outputs))
  return projections + attention_flops(length, width, rows, outputs) + mlp


def transformer_flops(num_blocks: int, length: int, width: int, mlp_ratio: int,
                      rows: int = 1, outputs: int | None = None) -> int:
  """A stack of `num_blocks` blocks whose last computes `outputs` tokens (default all).

  The final LayerNorm is element-wise: not counted.
  """
  return ((num_blocks - 1) * transformer_block_flops(length, width, mlp_ratio, rows)
          + transformer_block_flops(length, width, mlp_ratio, rows, outputs))


def mlp_flops(sizes, rows: int = 1) -> int:
  """Dense chain sizes[0] -> sizes[1] -> ... -> sizes[-1] on `rows` inputs."""
  return sum(dense_flops(a, b, rows) for a, b in zip(sizes[:-1], sizes[1:]))


def time_embedding_flops(width: int) -> int:
  """Fourier features -> Dense -> SiLU -> Dense, once per denoising step (t is a scalar)."""
  return 2 * dense_flops(width, width, 1)


def plan_flops(m: ModelSettings, p: PlanSettings) -> dict:
  """Hand count of one `plan(params, z, key)` call of `build_plan(m, p)`, broken down by network.

  Follows the code: the proposal's conditioning token is computed once per plan, the dynamics'
  conditioning tokens once per transition, time embeddings once per denoising step (shared by
  all candidates), the objective once per candidate, the actor once per transition on the
  P prior candidates. The last block of the proposal computes only the H action tokens and
  that of the dynamics only the noisy-latent token (the outputs that are read).

  Returns:
    {'proposal', 'dynamics', 'objective', 'actor', 'total'}: FLOPs (ints).
  """
  h, a, d, w, r = m.horizon, m.action_dim, m.latent_dim, m.width, m.mlp_ratio
  k, num_prior = p.num_candidates, p.num_prior_candidates
  n = k - num_prior
  action_steps = p.action_steps
  if p.warm_start_steps:
    action_steps = p.warm_start_steps  # Warm-started proposals run the short schedule only.

  proposal_step = (time_embedding_flops(w) + dense_flops(a, w, n * h)
                   + transformer_flops(m.proposal_blocks, h + 1, w, r, n, outputs=h)
                   + dense_flops(w, a, n * h))
  proposal = dense_flops(d, w, 1) + action_steps * proposal_step

  dynamics_step = (time_embedding_flops(w) + dense_flops(d, w, k)
                   + transformer_flops(m.dynamics_blocks, 3, w, r, k, outputs=1)
                   + dense_flops(w, d, k))
  transition_cond = dense_flops(d, w, k) + dense_flops(a, w, k)
  dynamics = h * (transition_cond + p.dynamics_steps * dynamics_step)

  actor = h * mlp_flops((d,) + tuple(m.actor_hidden) + (a,), num_prior) if num_prior else 0

  length = 2 * h + 1
  objective = (dense_flops(d, w, k * (h + 1)) + dense_flops(a, w, k * h)
               + transformer_flops(m.objective_blocks, length, w, r, k)
               + dense_flops(w, m.num_bins, k * h) + dense_flops(w, m.num_bins, k * (h + 1)))
  total = proposal + dynamics + objective + actor
  return dict(proposal=proposal, dynamics=dynamics, objective=objective, actor=actor,
              total=total)


# ---------------------------------------------------------------------------------------------
# XLA count, corrected for loop trip counts.


def xla_flops(fn: Callable, *args) -> float:
  """FLOPs XLA's cost analysis reports for jit(fn)(*args) (loop bodies counted once).

  args may be arrays or jax.ShapeDtypeStruct; nothing is executed.
  """
  return compiled_flops(jax.jit(fn).lower(*args).compile())


def compiled_flops(compiled) -> float:
  """FLOPs in the cost analysis of a compiled executable (`jit(f).lower(...).compile()`)."""
  cost = compiled.cost_analysis()
  if isinstance(cost, (list, tuple)):  # Older JAX returned one dict per device.
    cost = cost[0]
  return float(cost['flops'])


def _abstract_inputs(m: ModelSettings):
  params = jax.eval_shape(lambda key: init_params_from(m, key), jax.random.key(0))
  key = jax.eval_shape(lambda: jax.random.key(0))
  z = jax.ShapeDtypeStruct((m.latent_dim,), jnp.float32)
  return params, z, key


def xla_plan_flops(m: ModelSettings, p: PlanSettings, plan_fn: Callable | None = None,
                   plan_args: tuple | None = None, plan_once: float | None = None) -> dict:
  """Trip-count-corrected XLA FLOPs of one `plan` call (see the module docstring).

  Args:
    m: the model's settings (ModelSettings.from_config(config)).
    p: the planner's settings of `plan_fn` (PlanSettings.from_config(config), or the acting
      planner's: OnlineSettings.acting_plan).
    plan_fn: the jitted plan to analyse; default `build_plan(m, p)`.
    plan_args: its arguments (arrays or ShapeDtypeStructs); default (params, z, key). Pass
      (params, z, key, prev_sequence) for a warm-started call.
    plan_once: C(plan) if already known (from the caller's own compilation).
  Returns:
    {'plan_once': C(plan), 'proposal_step', 'transition', 'dynamics_step', 'total'} in FLOPs.
  """
  from ld_mpc_jax.plan import planner  # Local: planner imports nothing from here, keep it that way.
  nets = build_networks(m)
  h, a, w = m.horizon, m.action_dim, m.width
  k, n = p.num_candidates, p.num_candidates - p.num_prior_candidates
  params, z, key = _abstract_inputs(m)
  if plan_once is None:
    plan_fn = plan_fn or planner.build_plan(m, p)
    plan_once = xla_flops(plan_fn, *(plan_args or (params, z, key)))

  def proposal_step(prop_params, x, cond, key):
    variables = {'params': prop_params}
    model_fn = lambda a_t, t: nets.proposal.apply(variables, a_t, t, cond,
                                                  method=ActionProposal.denoise)
    return diffusion.sample(model_fn, x, key, 1, p.action_eta, m.prediction,
                            clip_x0=m.clip_actions)

  def dynamics_step(dyn_params, x, cond, key):
    variables = {'params': dyn_params}
    model_fn = lambda x_t, t: nets.dynamics.apply(variables, x_t, t, cond,
                                                  method=LatentDynamics.denoise)
    return diffusion.sample(model_fn, x, key, 1, p.dynamics_eta, m.prediction)

  f32 = lambda *shape: jax.ShapeDtypeStruct(shape, jnp.float32)
  prop = xla_flops(proposal_step, params['proposal'], f32(n, h, a), f32(n, 1, w), key)
  dyn = xla_flops(dynamics_step, params['dynamics'], f32(k, m.latent_dim),
                  f32(k, 2, w), key)
  # One transition (conditioning, actor prior, one dynamics step): the rollout's outer scan
  # with a single denoising step, counted once by XLA.
  rollout = planner.make_rollout(m, dataclasses.replace(p, dynamics_steps=1), nets)
  transition = xla_flops(rollout, params, z, f32(n, h, a), key)

  action_steps = p.action_steps
  if p.warm_start_steps:
    action_steps = p.warm_start_steps
  total = (plan_once + (action_steps - 1) * prop + (h - 1) * transition
           + h * (p.dynamics_steps - 1) * dyn)
  return dict(plan_once=plan_once, proposal_step=prop, transition=transition,
              dynamics_step=dyn, total=total)


def matmul_flops(n: int) -> int:
  """FLOPs of an [n, n] x [n, n] matrix product (for the peak measurement)."""
  return 2 * n ** 3


# ---------------------------------------------------------------------------------------------
# The MPPI baseline (ld_mpc_jax.plan.mppi with TD-MPC2's MLP world model).


def tdmpc2_mppi_flops(mppi_cfg, model_cfg) -> dict:
  """Hand count of one TD-MPC2 MPPI call (`mppi.make_tdmpc2_mppi`).

  Per iteration every one of the N sequences is rolled out H steps (reward and dynamics MLP per
  step), then pi and all Q heads run at z_H; the P prior trajectories cost H policy and H - 1
  dynamics calls once per plan.

  Returns:
    {'prior', 'iterations', 'total'}: FLOPs (ints).
  """
  c, m = model_cfg, mppi_cfg
  d, a, w = c.latent_dim, c.action_dim, c.mlp_dim
  dynamics = mlp_flops((d + a, w, w, d))
  reward = mlp_flops((d + a, w, w, c.num_bins))
  policy = mlp_flops((d, w, w, 2 * a))
  q = c.num_q * mlp_flops((d + a, w, w, c.num_bins))
  per_sequence = m.horizon * (dynamics + reward) + policy + q
  iterations = m.iterations * m.num_samples * per_sequence
  prior = m.num_prior * (m.horizon * policy + (m.horizon - 1) * dynamics)
  return dict(prior=prior, iterations=iterations, total=prior + iterations)


def xla_mppi_flops(plan_fn: Callable, plan_args: tuple, value_fn: Callable, params,
                   mppi_cfg, plan_once: float | None = None) -> dict:
  """Trip-count-corrected XLA FLOPs of one MPPI call.

  The iteration loop is a lax.scan, counted once in C(plan); the missing (iterations - 1) are
  added as the cost of value_fn on the [N, H, A] batch it sees (the elite update is a few
  thousand FLOPs and left out). The horizon inside value_fn is unrolled, so it needs no correction.
  """
  if plan_once is None:
    plan_once = xla_flops(plan_fn, *plan_args)
  z = plan_args[1]
  actions = jax.ShapeDtypeStruct((mppi_cfg.num_samples, mppi_cfg.horizon, mppi_cfg.action_dim),
                                 jnp.float32)
  key = jax.eval_shape(lambda: jax.random.key(0))
  value = xla_flops(value_fn, params, z, actions, key)
  total = plan_once + (mppi_cfg.iterations - 1) * value
  return dict(plan_once=plan_once, value=value, total=total)
