"""Policy modes: how each policy turns an observation into an action, one decision at a time.

The planner, the actor prior, the proposal alone and MPPI on the learned model, each a
registry entry (POLICY_MODES) whose act works on the latent; `make_act_fn` puts the encoder
(and, with `plan.latent_filter`, the model's filter of the latent) in front of it.
ld_mpc_jax.plan.agent jits and batches them.
"""

import dataclasses
from typing import Any, Callable, NamedTuple, Tuple

import jax
import jax.numpy as jnp
import ml_collections

from ld_mpc_jax.model import dynamics
from ld_mpc_jax.model.config_checks import check_config
from ld_mpc_jax.plan.search import validate_plan
from ld_mpc_jax.model.models import build_networks
from ld_mpc_jax.model.settings import ModelSettings, PlanSettings
from ld_mpc_jax.ops.numerics import rms_normalize
from ld_mpc_jax.ops.registry import Registry
from ld_mpc_jax.plan.mppi import make_ldmpc_mppi
from ld_mpc_jax.plan.planner import build_plan, make_propose


@dataclasses.dataclass(frozen=True)
class ActSettings:
  """What a policy mode is built from: the model's settings, the planner's (the acting
  planner's are a dataclasses.replace of the evaluation's: OnlineSettings.acting_plan) and MPPI's.
  Frozen and hashable: equal settings share one jitted act (ld_mpc_jax.plan.agent)."""
  model: ModelSettings
  plan: PlanSettings
  mppi: Tuple[Tuple[str, Any], ...]  # config.mppi's items: checked when the mode is 'mppi'.

  @classmethod
  def from_config(cls, config: ml_collections.ConfigDict) -> 'ActSettings':
    """The settings of a config, after its checks (one-line ValueErrors)."""
    check_config(config)
    model, plan = ModelSettings.from_config(config), PlanSettings.from_config(config)
    validate_plan(plan, model)
    return cls(model, plan, tuple(sorted(config.mppi.items())))


# What a decision reports beside its action: float32 [7] = (kind of the winning candidate, an
# index into search.CANDIDATES.names() or -1 for policies that do not plan; the refinement round it
# came from; 1 if the planner departed from the actor prior's own sequence, else 0; the fallback
# (`plan.fallback_drop`, with safe selection): 1 once it has handed the episode to the actor
# prior, 0 before, -1 for policies without it; then planner.PlanOutput.spread [2] and
# proposal_elites while acting (`intrinsic` given), else -1).
NO_PLAN_INFO = (-1, 0, 0, -1, -1, -1, -1)

# Policy modes: name -> PolicyMode. A mode's act(params, z [latent_dim], key, prev, noise [],
# intrinsic) -> (action [A], carry, info [7]) is built by make_act(settings, nets) (ActSettings),
# not jitted;
# `intrinsic` (acting only, objective.Intrinsic or None) is the planner's; `carry` is what
# the next decision of the episode gets as `prev` (the sequence [H, A]: the planner's plan or
# MPPI's mean; the planner with the fallback adds its planner.Guard);
# `uses_prev(plan)` (PlanSettings): whether it acts on the previous decision's carry.
POLICY_MODES = Registry('policy mode', 'mode')


class PolicyMode(NamedTuple):
  make_act: Callable
  uses_prev: Callable = lambda plan: False


def _encode(nets, params, obs):
  return nets.encoder.apply({'params': params['encoder']}, obs)


def _no_plan_info():
  return jnp.asarray(NO_PLAN_INFO, jnp.float32)


def _plan_act(s: ActSettings, nets):
  """The planner (ld_mpc_jax.plan.planner); info is (kind, iteration, departed, fallen). With
  `plan.fallback_drop` > 0 what it carries to the next decision is (sequence, Guard): the
  previous sequence and the fallback's state (planner.Guard); else the sequence alone."""
  plan = build_plan(s.model, s.plan)
  guarded, warm = s.plan.gates[1], s.plan.warm_start_steps > 0

  def act(params, z, key, prev, noise, intrinsic=None):
    if guarded:  # The sequence travels only to warm-start, as without the guard.
      sequence, guard = prev if prev is not None else (None, None)
      sequence = sequence if warm else None
    else:
      sequence, guard = prev, None
    out = plan(params, z, key, sequence, noise, guard, intrinsic)
    fallen = out.guard.fallen if guarded else -1
    info = jnp.concatenate([jnp.stack([out.kind, out.iteration, out.departed, fallen]).astype(
        jnp.float32), out.spread, out.proposal_elites[None]])
    return out.action, (out.sequence, out.guard) if guarded else out.sequence, info
  return act


def _with_noise(action, noise, key):
  """`action` plus N(0, noise^2), clipped to the bounds; exactly `action` where noise is 0."""
  noisy = jnp.clip(action + noise * jax.random.normal(key, action.shape), -1.0, 1.0)
  return jnp.where(noise > 0, noisy, action)


def _actor_act(s: ActSettings, nets):
  """The actor prior's mode, held over the horizon; `noise` (acting online with
  `online.act_mode = 'actor'`, or `eval.action_noise`) is the std of Gaussian noise on its
  action, 0 in evaluation by default."""
  def act(params, z, key, prev, noise, intrinsic=None):
    a = nets.actor.apply({'params': params['actor']}, z)
    a = _with_noise(a, noise, key)
    return a, jnp.broadcast_to(a, (s.model.horizon,) + a.shape), _no_plan_info()
  return act


def _mppi_act(s: ActSettings, nets):
  """MPPI on the learned model (config.mppi); `prev` is its previous Gaussian mean."""
  mppi_plan = make_ldmpc_mppi(s.model, s.plan, s.mppi)

  def act(params, z, key, prev, noise, intrinsic=None):
    out = mppi_plan(params, z, key, prev)
    return (_with_noise(out.action, noise, jax.random.fold_in(key, 7)), out.mean,
            _no_plan_info())
  return act


def _proposal_act(s: ActSettings, nets):
  """One sample of the proposal alone (single-step kinds: the one action, held)."""
  propose = make_propose(s.model, s.plan, nets)

  def act(params, z, key, prev, noise, intrinsic=None):
    seq = jnp.clip(propose(params, z, key, 1)[0], -1.0, 1.0)
    if seq.shape[0] == 1:  # Single-step proposal kinds: hold the one action.
      seq = jnp.repeat(seq, s.model.horizon, axis=0)
    return (_with_noise(seq[0], noise, jax.random.fold_in(key, 7)), seq, _no_plan_info())
  return act


POLICY_MODES.register('plan', PolicyMode(
    _plan_act, lambda plan: plan.warm_start_steps > 0 or plan.gates[1]))
POLICY_MODES.register('actor', PolicyMode(_actor_act))
POLICY_MODES.register('proposal', PolicyMode(_proposal_act))
POLICY_MODES.register('mppi', PolicyMode(_mppi_act, lambda plan: True))
MODES = POLICY_MODES.names()  # ('plan', 'actor', 'proposal', 'mppi'); the registry's names.


def make_act_fn(s: ActSettings, mode: str) -> Callable:
  """act(params, obs [obs_dim], key, prev, noise [], intrinsic=None) -> (action [A], carry,
  info [7]), not jitted: the encoder's latent (filtered with `plan.latent_filter`), then the
  mode's act. `noise`: std of Gaussian noise on the executed action of the planner or the actor
  prior (acting only); `intrinsic`: the planner's (acting only)."""
  entry, nets = POLICY_MODES.get(mode), build_networks(s.model)
  inner = entry.make_act(s, nets)
  if s.plan.latent_filter == 0:
    return lambda params, obs, key, prev, noise, intrinsic=None: inner(
        params, _encode(nets, params, obs), key, prev, noise, intrinsic)
  return _filtered(s, nets, inner, entry.uses_prev(s.plan))


def _filtered(s: ActSettings, nets, inner: Callable, inner_prev: bool) -> Callable:
  """`inner` acting on the latent filtered with the model: z_t = rms(f z'_t + (1 - f) enc(o_t)),
  z'_t the dynamics model's one-step prediction from the previous decision's (filtered) latent and
  executed action (f = `plan.latent_filter`; base.py). Its carry is (the inner carry, z_t, a_t)."""
  f = s.plan.latent_filter
  transition = dynamics.make_transition(s.model, nets.dynamics, s.plan.dynamics_steps,
                                        s.plan.dynamics_eta)

  def act(params, obs, key, prev, noise, intrinsic=None):
    z = _encode(nets, params, obs)
    carry = None
    if prev is not None:
      carry, z_prev, a_prev = prev
      z_pred = transition(params, z_prev[None], a_prev[None], jax.random.fold_in(key, 11))[0]
      z = rms_normalize(f * z_pred + (1.0 - f) * z)
    action, carry, info = inner(params, z, key, carry if inner_prev else None, noise, intrinsic)
    return action, (carry, z, action), info
  return act


def carried_sequence(plan: PlanSettings, carry):
  """The planner's chosen sequence [..., H, A] in the carry of the 'plan' mode's act (inside
  the latent filter's carry, beside the fallback's Guard: `_plan_act`, `_filtered`)."""
  if plan.latent_filter > 0:
    carry = carry[0]
  return carry[0] if plan.gates[1] else carry


def uses_prev(plan: PlanSettings, mode: str) -> bool:
  """Whether `mode` acts on the previous decision's carry (warm-started planner, MPPI; every
  mode with `plan.latent_filter`)."""
  return plan.latent_filter > 0 or POLICY_MODES.get(mode).uses_prev(plan)
