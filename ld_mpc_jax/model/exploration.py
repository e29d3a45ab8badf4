"""Acting settings of online training: the planner's exploration noise, pessimism and search while
acting, its intrinsic exploration term in J (optimism over the value members and the dynamics
draws' disagreement, annealed), and the noise on the executed action (white inside the jitted
plan, or correlated here). Evaluation never uses them."""

import dataclasses
from typing import Tuple

import ml_collections
import numpy as np

from ld_mpc_jax.configs import schedule_end
from ld_mpc_jax.model import proposals
from ld_mpc_jax.model.objective import Intrinsic
from ld_mpc_jax.model.settings import PlanSettings

SCHEDULES = ('constant', 'linear')


def acting_plan(config: ml_collections.ConfigDict) -> PlanSettings:
  """The planner's settings while acting: `dataclasses.replace` of the evaluation's
  (PlanSettings.from_config) with `config.online`'s exploration noise on its candidates, its
  acting pessimism (`online.act_pessimism`; evaluation keeps `plan.pessimism`): unfamiliar
  states are model error offline, opportunity online; and its acting selection
  (`online.act_safe_selection`; evaluation keeps `plan.safe_selection`; `plan.safe_confirm`
  and `plan.fallback_drop` apply while acting only with it), its search
  (`online.act_num_gaussian`, `online.act_iterations`; evaluation keeps `plan.num_gaussian`
  and `plan.iterations`), its dynamics draws (`online.act_dynamics_draws`, 0: the plan's) and,
  with `online.act_proposal` off, no proposal candidates. Under `online.act_schedule='linear'`
  the acting pessimism is no setting but the plan's traced `intrinsic` (ActingSchedule), so
  `pessimism` is 0 here."""
  o, p = config.online, PlanSettings.from_config(config)
  return dataclasses.replace(
      p, action_noise_std=o.action_noise_std, prior_noise_std=o.prior_noise_std,
      pessimism=o.act_pessimism if o.act_schedule == 'constant' else 0.0,
      safe_selection=o.act_safe_selection, safe_confirm=p.safe_confirm and o.act_safe_selection,
      # The fallback hands the rest of an episode to the actor prior: a safe-selection gate too.
      fallback_drop=p.fallback_drop if o.act_safe_selection else 0.0,
      num_gaussian=o.act_num_gaussian, iterations=o.act_iterations,
      dynamics_draws=o.act_dynamics_draws or p.dynamics_draws,
      # Without the proposal, the first round holds the actor prior's candidates alone.
      num_candidates=p.num_candidates if o.act_proposal else p.num_prior_candidates)


def _linear(start: float, end: float, env_steps: int, first: int, total: int) -> float:
  """start at `first` environment steps (and before), end at `total` (and after), linear between."""
  frac = np.clip((env_steps - first) / max(total - first, 1), 0.0, 1.0)
  return float(start + frac * (end - start))


@dataclasses.dataclass(frozen=True)
class ActingSchedule:
  """The acting planner's settings that anneal with environment steps (`config.online`), built
  once per run (`from_config`) where it knows when learning starts.

  Each is linear from its start value at its first step to its end value at `end` (= schedule_end:
  `online.schedule_steps`, or `online.env_steps` where that is 0), constant after:
  - the executed action's noise std (`exec_noise_start` -> `exec_noise_end`), from `learn_start`;
  - under `online.act_schedule='linear'` the intrinsic term's weights (`act_pessimism`,
    `act_disagreement`, `act_novelty` -> their `_end`), from `plan_start` (the first planner
    wave); under 'constant' those keep their start values.
  """
  schedule: str  # online.act_schedule: 'constant' | 'linear'.
  end: int
  learn_start: int
  plan_start: int
  exec_noise_start: float
  exec_noise_end: float
  act_pessimism: float
  act_pessimism_end: float
  act_disagreement: float
  act_disagreement_end: float
  act_novelty: float
  act_novelty_end: float

  @classmethod
  def from_config(cls, config: ml_collections.ConfigDict, learn_start: int) -> 'ActingSchedule':
    """`learn_start`: environment steps where updates start. The first planner wave follows the
    actor prior's seed waves with demonstrations and `online.demo_seed_actor`, else it is there."""
    o = config.online
    names = ('exec_noise_start', 'exec_noise_end', 'act_pessimism', 'act_pessimism_end',
             'act_disagreement', 'act_disagreement_end', 'act_novelty', 'act_novelty_end')
    first = o.seed_steps if o.demos and o.demo_seed_actor else learn_start
    return cls(schedule=o.act_schedule, end=schedule_end(config), learn_start=learn_start,
               plan_start=first, **{name: float(o[name]) for name in names})

  def executed_noise(self, env_steps: int) -> float:
    """Std of the noise on the executed action at `env_steps`."""
    return _linear(self.exec_noise_start, self.exec_noise_end, env_steps, self.learn_start,
                   self.end)

  def _scheduled(self, name: str, env_steps: int) -> float:
    start = getattr(self, name)
    if self.schedule == 'constant':
      return start
    return _linear(start, getattr(self, f'{name}_end'), env_steps, self.plan_start, self.end)

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
    float32 scalars): `exploration`'s values and `novelty`'s, except the pessimism under the
    'constant' schedule, which `acting_plan` sets as the plan's `pessimism` (0 here)."""
    pessimism, disagreement = self.exploration(env_steps)
    if self.schedule == 'constant':
      pessimism = 0.0
    return Intrinsic(pessimism=np.float32(pessimism), disagreement=np.float32(disagreement),
                     novelty=np.float32(self.novelty(env_steps)))


def validate_acting(config: ml_collections.ConfigDict) -> None:
  """One-line ValueErrors for the acting planner's exploration settings (`config.online`)."""
  o, p = config.online, config.plan
  if o.act_schedule not in SCHEDULES:
    raise ValueError(f'config.online.act_schedule must be one of {SCHEDULES}, '
                     f'got {o.act_schedule!r}')
  if not isinstance(o.schedule_steps, int) or o.schedule_steps < 0:
    raise ValueError('config.online.schedule_steps must be an integer >= 0 (0: online.env_steps), '
                     f'got {o.schedule_steps!r}')
  if not isinstance(o.act_dynamics_draws, int) or o.act_dynamics_draws < 0:
    raise ValueError('config.online.act_dynamics_draws must be an integer >= 0, '
                     f'got {o.act_dynamics_draws!r}')
  weights = (o.act_disagreement,) + ((o.act_disagreement_end,) if o.act_schedule == 'linear'
                                      else ())
  if any(weights) and (o.act_dynamics_draws or p.dynamics_draws) < 2:
    raise ValueError('config.online.act_disagreement needs several dynamics draws while acting '
                     'to disagree: set config.online.act_dynamics_draws >= 2')
  novelty_weights = (o.act_novelty,) + ((o.act_novelty_end,) if o.act_schedule == 'linear'
                                         else ())
  if min(novelty_weights) < 0:
    raise ValueError('config.online.act_novelty and act_novelty_end must be >= 0, got '
                     f'{o.act_novelty} and {o.act_novelty_end}')
  if any(novelty_weights) and not config.loss.w_novelty > 0:
    raise ValueError('config.online.act_novelty needs the learned exploration value: set '
                     'config.loss.w_novelty > 0 (its loss weight) too')
  if o.act_proposal:
    return
  if not proposals.PROPOSALS.get(config.model.proposal_type).sequence:
    raise ValueError('config.online.act_proposal=False drops whole proposal sequences from the '
                     f'first round; proposal_type {config.model.proposal_type!r} has none')
  if p.num_prior_candidates + o.act_num_gaussian < 1:
    raise ValueError('config.online.act_proposal=False leaves no candidate while acting: set '
                     'config.plan.num_prior_candidates or config.online.act_num_gaussian >= 1')


def ar1_noise(noise: np.ndarray, std: float, corr: float,
              rng: np.random.Generator) -> np.ndarray:
  """The next AR(1) (discrete Ornstein-Uhlenbeck) noise: corr x noise + sqrt(1 - corr^2) x std x
  N(0, 1), same shape as `noise`; its stationary std is `std`."""
  return corr * noise + np.sqrt(1.0 - corr**2) * std * rng.standard_normal(noise.shape)
