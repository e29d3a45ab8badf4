"""Online training's schedules: the acting planner's intrinsic exploration term in J (optimism over
the value members and the dynamics draws' disagreement, annealed) and the noise on the executed
action (white inside the jitted plan, or correlated here: `ar1_noise`). The acting planner's
fixed settings are OnlineSettings.acting_plan. Evaluation uses neither."""

import dataclasses
from typing import Tuple

import numpy as np

from ld_mpc_jax.model.objective import Intrinsic
from ld_mpc_jax.online.settings import OnlineSettings


def _linear(start: float, end: float, env_steps: int, first: int, total: int) -> float:
  """start at `first` environment steps (and before), end at `total` (and after), linear between."""
  frac = np.clip((env_steps - first) / max(total - first, 1), 0.0, 1.0)
  return float(start + frac * (end - start))


@dataclasses.dataclass(frozen=True)
class ActingSchedule:
  """The acting planner's settings that anneal with environment steps (`config.online`), built
  once per run where it knows when learning starts.

  Each is linear from its start value at its first step to its end value at `schedule_end`
  (`online.schedule_steps`, or `online.env_steps` where that is 0), constant after:
  - the executed action's noise std (`exec_noise_start` -> `exec_noise_end`), from `learn_start`;
  - under `online.act_schedule='linear'` the intrinsic term's weights (`act_pessimism`,
    `act_disagreement`, `act_novelty` -> their `_end`), from `plan_start` (the first planner
    wave); under 'constant' those keep their start values.
  """
  online: OnlineSettings
  learn_start: int  # Environment steps where updates start.

  @property
  def plan_start(self) -> int:
    """The first planner wave: after the actor prior's seed waves with demonstrations and
    `online.demo_seed_actor`, else where learning starts."""
    o = self.online
    return o.seed_steps if o.demos and o.demo_seed_actor else self.learn_start

  def executed_noise(self, env_steps: int) -> float:
    """Std of the noise on the executed action at `env_steps`."""
    o = self.online
    return _linear(o.exec_noise_start, o.exec_noise_end, env_steps, self.learn_start,
                   o.schedule_end)

  def _scheduled(self, name: str, env_steps: int) -> float:
    o, start = self.online, float(getattr(self.online, name))
    if o.act_schedule == 'constant':
      return start
    return _linear(start, getattr(o, f'{name}_end'), env_steps, self.plan_start, o.schedule_end)

  def exploration(self, env_steps: int) -> Tuple[float, float]:
    """(pessimism, disagreement weight) of the acting planner at `env_steps`."""
    return (self._scheduled('act_pessimism', env_steps),
            self._scheduled('act_disagreement', env_steps))

  def novelty(self, env_steps: int) -> float:
    """Weight of the learned exploration value in the acting planner's J at `env_steps`
    (ld_mpc_jax.model.novelty)."""
    return self._scheduled('act_novelty', env_steps)

  def intrinsic(self, env_steps: int) -> Intrinsic:
    """The acting planner's traced intrinsic term at `env_steps` (build_plan's `intrinsic`,
    float32 scalars), except the pessimism under the 'constant' schedule, which
    OnlineSettings.acting_plan sets as the plan's `pessimism` (0 here)."""
    pessimism, disagreement = self.exploration(env_steps)
    if self.online.act_schedule == 'constant':
      pessimism = 0.0
    return Intrinsic(pessimism=np.float32(pessimism), disagreement=np.float32(disagreement),
                     novelty=np.float32(self.novelty(env_steps)))


def ar1_noise(noise: np.ndarray, std: float, corr: float,
              rng: np.random.Generator) -> np.ndarray:
  """The next AR(1) (discrete Ornstein-Uhlenbeck) noise: corr x noise + sqrt(1 - corr^2) x std x
  N(0, 1), same shape as `noise`; its stationary std is `std`."""
  return corr * noise + np.sqrt(1.0 - corr**2) * std * rng.standard_normal(noise.shape)
