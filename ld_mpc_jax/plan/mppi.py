"""MPPI planning in the style of TD-MPC2, generic over the world model.

`make_mppi_plan(mppi_config, value_fn, prior_fn)` builds one jitted function that refines a
diagonal Gaussian over action sequences [H, A] for a fixed number of iterations (TD-MPC2's
`plan`): each iteration samples N - P sequences from the Gaussian (clipped to [-1, 1]), adds the
P policy-prior trajectories, scores all N with `value_fn`, keeps the top E, and refits mean and
std with softmax weights exp(temperature (v - v_max)) over the elites. The executed action is the
first action of an elite drawn from those weights (TD-MPC2's `gumbel_softmax_sample`). The world
model enters only through

  value_fn(params, z [D], actions [N, H, A], key) -> [N]  returns of the rolled-out sequences,
  prior_fn(params, z [D], key, num) -> [num, H, A]       policy-prior trajectories (optional),

so the same MPPI runs on TD-MPC2's MLP world model (`make_tdmpc2_value_fn`, the baseline of the
planning benchmark) and on this project's diffusion dynamics + sequence objective
(`make_ldmpc_value_fn`).

The TD-MPC2 model itself lives in ld_mpc_jax/model/tdmpc2_world.py; here are its MPPI adapters.
"""

import dataclasses
from typing import Any, Callable, Optional, Tuple

import flax
import jax
import jax.numpy as jnp
import ml_collections

from ld_mpc_jax.model.settings import ModelSettings, PlanSettings
from ld_mpc_jax.model.tdmpc2_world import TDMPC2Config, TDMPC2Model

ValueFn = Callable[[dict, jnp.ndarray, jnp.ndarray, jax.Array], jnp.ndarray]
PriorFn = Callable[[dict, jnp.ndarray, jax.Array, int], jnp.ndarray]


@dataclasses.dataclass(frozen=True)
class MPPIConfig:
  """Static MPPI hyperparameters; the defaults are TD-MPC2's."""
  action_dim: int = 4
  horizon: int = 3
  num_samples: int = 512  # N: sequences scored per iteration, prior trajectories included.
  num_elites: int = 64  # E.
  num_prior: int = 24  # P: policy-prior trajectories among the N.
  iterations: int = 6
  temperature: float = 0.5  # Elite weights exp(temperature * (v - v_max)).
  min_std: float = 0.05
  max_std: float = 2.0

  def __post_init__(self):
    if not 0 <= self.num_prior < self.num_samples:
      raise ValueError(f'num_prior must be in [0, num_samples), got {self.num_prior}')
    if not 1 <= self.num_elites <= self.num_samples:
      raise ValueError(f'num_elites must be in [1, num_samples], got {self.num_elites}')
    if self.horizon < 1 or self.iterations < 1 or self.action_dim < 1:
      raise ValueError('horizon, iterations and action_dim must be >= 1')
    if not 0 < self.min_std <= self.max_std:
      raise ValueError(f'need 0 < min_std <= max_std, got {self.min_std}, {self.max_std}')


@flax.struct.dataclass
class MPPIOutput:
  """What the MPPI plan returns; E elites, horizon H, action size A."""
  action: jnp.ndarray  # [A] first action of an elite drawn from the softmax weights.
  mean: jnp.ndarray  # [H, A] final Gaussian mean (pass as prev_mean at the next step).
  std: jnp.ndarray  # [H, A] final Gaussian std.
  elite_actions: jnp.ndarray  # [E, H, A] last iteration's elites.
  elite_values: jnp.ndarray  # [E] their values.


def make_mppi_plan(cfg: MPPIConfig, value_fn: ValueFn,
                   prior_fn: Optional[PriorFn] = None) -> Callable:
  """Builds the jitted MPPI planner.

  Args:
    cfg: MPPI hyperparameters (static).
    value_fn: (params, z [D], actions [N, H, A], key) -> values [N].
    prior_fn: (params, z [D], key, num) -> [num, H, A] policy trajectories; required if
      cfg.num_prior > 0.
  Returns:
    plan(params, z [D], key, prev_mean [H, A] | None) -> MPPIOutput. prev_mean is the previous
    step's mean; it is shifted by one step (TD-MPC2's warm start); None starts from zeros.
  """
  if cfg.num_prior and prior_fn is None:
    raise ValueError('cfg.num_prior > 0 needs a prior_fn')
  n, e, p, h, a = cfg.num_samples, cfg.num_elites, cfg.num_prior, cfg.horizon, cfg.action_dim

  def elite_weights(values):
    w = jnp.exp(cfg.temperature * (values - jnp.max(values)))
    return w / jnp.sum(w)

  def plan(params, z, key, prev_mean=None) -> MPPIOutput:
    prior_key, sample_key, value_key, select_key = jax.random.split(key, 4)
    mean = jnp.zeros((h, a))
    if prev_mean is not None:
      mean = mean.at[:-1].set(prev_mean[1:])
    std = jnp.full((h, a), cfg.max_std)
    prior = prior_fn(params, z, prior_key, p) if p else jnp.zeros((0, h, a))

    def iteration(carry, i):
      mean, std, _, _ = carry
      noise = jax.random.normal(jax.random.fold_in(sample_key, i), (n - p, h, a))
      sampled = jnp.clip(mean + std * noise, -1.0, 1.0)
      actions = jnp.concatenate([prior, sampled], axis=0)  # [N, H, A]
      values = jnp.nan_to_num(value_fn(params, z, actions, jax.random.fold_in(value_key, i)))
      elite_values, idx = jax.lax.top_k(values, e)
      elite_actions = actions[idx]  # [E, H, A]
      w = elite_weights(elite_values)[:, None, None]
      mean = jnp.sum(w * elite_actions, axis=0)
      std = jnp.sqrt(jnp.sum(w * (elite_actions - mean) ** 2, axis=0))
      std = jnp.clip(std, cfg.min_std, cfg.max_std)
      return (mean, std, elite_actions, elite_values), None

    init = (mean, std, jnp.zeros((e, h, a)), jnp.zeros((e,)))
    (mean, std, elite_actions, elite_values), _ = jax.lax.scan(
        iteration, init, jnp.arange(cfg.iterations))
    pick = jax.random.categorical(select_key, jnp.log(elite_weights(elite_values)))
    action = jnp.clip(elite_actions[pick, 0], -1.0, 1.0)
    return MPPIOutput(action=action, mean=mean, std=std, elite_actions=elite_actions,
                      elite_values=elite_values)

  return jax.jit(plan)


# ---------------------------------------------------------------------------------------------
# TD-MPC2's MLP world model (ld_mpc_jax.model.tdmpc2_world) under MPPI: the baseline.


def make_tdmpc2_value_fn(cfg: TDMPC2Config) -> ValueFn:
  """TD-MPC2's `_estimate_value`: sum_t gamma^t r_t + gamma^H mean of 2 random Qs at pi(z_H).

  The horizon (3) is unrolled statically; all 5 Q heads are evaluated, as TD-MPC2 does.
  """
  model = TDMPC2Model(cfg)
  call = lambda params, method, *args: model.apply({'params': params}, *args, method=method)

  def value_fn(params, z, actions, key):
    n, horizon = actions.shape[:2]
    zs = jnp.broadcast_to(z, (n,) + z.shape)
    ret, discount = jnp.zeros((n,)), 1.0
    for t in range(horizon):
      ret = ret + discount * call(params, TDMPC2Model.reward, zs, actions[:, t])
      zs = call(params, TDMPC2Model.next, zs, actions[:, t])
      discount *= cfg.gamma
    pi_key, q_key = jax.random.split(key)
    q = call(params, TDMPC2Model.q_all, zs, call(params, TDMPC2Model.pi, zs, pi_key))
    pair = jax.random.choice(q_key, cfg.num_q, (2,), replace=False)
    return ret + discount * jnp.mean(q[pair], axis=0)

  return value_fn


def make_tdmpc2_prior_fn(cfg: TDMPC2Config, horizon: int) -> PriorFn:
  """Policy trajectories: a_t = pi(z_t), z_{t+1} = next(z_t, a_t), for t < H (unrolled)."""
  model = TDMPC2Model(cfg)
  call = lambda params, method, *args: model.apply({'params': params}, *args, method=method)

  def prior_fn(params, z, key, num):
    zs = jnp.broadcast_to(z, (num,) + z.shape)
    actions = []
    for t in range(horizon):
      actions.append(call(params, TDMPC2Model.pi, zs, jax.random.fold_in(key, t)))
      if t < horizon - 1:
        zs = call(params, TDMPC2Model.next, zs, actions[-1])
    return jnp.stack(actions, axis=1)

  return prior_fn


def make_tdmpc2_mppi(mppi_cfg: MPPIConfig = MPPIConfig(),
                     model_cfg: TDMPC2Config = TDMPC2Config()) -> Callable:
  """The TD-MPC2 baseline: plan(params, z [latent_dim], key, prev_mean) -> MPPIOutput."""
  prior_fn = make_tdmpc2_prior_fn(model_cfg, mppi_cfg.horizon) if mppi_cfg.num_prior else None
  return make_mppi_plan(mppi_cfg, make_tdmpc2_value_fn(model_cfg), prior_fn)


# ---------------------------------------------------------------------------------------------
# This project's world model under MPPI.


def make_ldmpc_value_fn(m: ModelSettings, plan: PlanSettings) -> ValueFn:
  """J of each sequence under LD-MPC's diffusion dynamics and learned sequence objective.

  MPPI's horizon must equal the model's. The rollout is the planner's own (K = N candidates,
  no actor-prior mixing: MPPI supplies its prior trajectories itself).
  """
  from ld_mpc_jax.model import objective  # pylint: disable=g-import-not-at-top
  from ld_mpc_jax.plan import planner  # pylint: disable=g-import-not-at-top
  from ld_mpc_jax.model.models import build_networks  # pylint: disable=g-import-not-at-top
  nets = build_networks(m)
  score = objective.make_score(m, nets, plan.pessimism, plan.progress_weight)

  def value_fn(params, z, actions, key):
    p = dataclasses.replace(plan, num_candidates=actions.shape[0], num_prior_candidates=0)
    _, latents = planner.make_rollout(m, p, nets)(params, z, actions, key)
    return score(params, latents, actions)

  return value_fn


def make_ldmpc_prior_fn(m: ModelSettings, plan: PlanSettings) -> PriorFn:
  """Actor-prior trajectories of LD-MPC's actor rolled out through its learned dynamics."""
  from ld_mpc_jax.plan import planner
  from ld_mpc_jax.model.models import build_networks
  nets = build_networks(m)
  h, a = m.horizon, m.action_dim

  def prior_fn(params, z, key, num):
    p = dataclasses.replace(plan, num_candidates=num, num_prior_candidates=num)
    actions, _ = planner.make_rollout(m, p, nets)(params, z, jnp.zeros((0, h, a)), key)
    return actions

  return prior_fn


def make_ldmpc_mppi(m: ModelSettings, plan: PlanSettings, mppi: Tuple[Tuple[str, Any], ...]
                    ) -> Callable:
  """MPPI (`mppi`: the items of `config.mppi`, checked here: MPPIConfig) on LD-MPC's learned
  dynamics, objective and actor prior, at the model's horizon and action size.

  Returns plan(params, z [latent_dim], key, prev_mean [H, A] | None) -> MPPIOutput.
  """
  try:
    cfg = MPPIConfig(action_dim=m.action_dim, horizon=m.horizon, **dict(mppi))
  except ValueError as err:
    raise ValueError(f'config.mppi: {err}') from None
  prior_fn = make_ldmpc_prior_fn(m, plan) if cfg.num_prior else None
  return make_mppi_plan(cfg, make_ldmpc_value_fn(m, plan), prior_fn)
