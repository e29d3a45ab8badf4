"""Acting settings of online training: the planner's exploration noise and pessimism while
acting, and the noise on the executed action (white inside the jitted plan, or correlated
here). Evaluation never uses them."""

import ml_collections
import numpy as np


def acting_config(config: ml_collections.ConfigDict) -> ml_collections.ConfigDict:
  """A copy of config for the planner while acting: `config.online`'s exploration noise on its
  candidates, its acting pessimism (`online.act_pessimism`; evaluation keeps `plan.pessimism`):
  unfamiliar states are model error offline, opportunity online; and its acting selection
  (`online.act_safe_selection`; evaluation keeps `plan.safe_selection`; `plan.safe_confirm`
  and `plan.fallback_drop` apply while acting only with it), and its search
  (`online.act_num_gaussian`, `online.act_iterations`; evaluation keeps `plan.num_gaussian`
  and `plan.iterations`)."""
  c = ml_collections.ConfigDict(config.to_dict())
  c.plan.action_noise_std = config.online.action_noise_std
  c.plan.prior_noise_std = config.online.prior_noise_std
  c.plan.pessimism = config.online.act_pessimism
  c.plan.safe_selection = config.online.act_safe_selection
  c.plan.safe_confirm = config.plan.safe_confirm and config.online.act_safe_selection
  # The fallback hands the rest of an episode to the actor prior: a safe-selection gate too.
  c.plan.fallback_drop = config.plan.fallback_drop if config.online.act_safe_selection else 0.0
  c.plan.num_gaussian = config.online.act_num_gaussian
  c.plan.iterations = config.online.act_iterations
  return c


def executed_noise(config: ml_collections.ConfigDict, env_steps: int, learn_start: int) -> float:
  """Std of the noise on the executed action at `env_steps`: linear from
  `online.exec_noise_start` when the planner starts acting to `online.exec_noise_end` at
  `online.env_steps`."""
  o = config.online
  frac = np.clip((env_steps - learn_start) / max(o.env_steps - learn_start, 1), 0.0, 1.0)
  return float(o.exec_noise_start + frac * (o.exec_noise_end - o.exec_noise_start))


def ar1_noise(noise: np.ndarray, std: float, corr: float,
              rng: np.random.Generator) -> np.ndarray:
  """The next AR(1) (discrete Ornstein-Uhlenbeck) noise: corr x noise + sqrt(1 - corr^2) x std x
  N(0, 1), same shape as `noise`; its stationary std is `std`."""
  return corr * noise + np.sqrt(1.0 - corr**2) * std * rng.standard_normal(noise.shape)
