"""Online training's settings (`config.online`), frozen, with their checks beside them.

  online = OnlineSettings.from_config(config)   # config.online, and what its checks read elsewhere
  online.check(model, plan)                     # one-line ValueErrors naming the field

Defaults and the reasons for them stay in configs/door_open_online.py (`online_settings`); an
offline config has no `online` section: build them where `configs.online_enabled(config)`.
"""

import dataclasses
import os
from typing import List, Tuple

import ml_collections

from ld_mpc_jax.data import demos as demos_lib
from ld_mpc_jax.model import proposals
from ld_mpc_jax.plan import search
from ld_mpc_jax.model.settings import ModelSettings, PlanSettings, _Hashable

# Policy modes (ld_mpc_jax.plan.agent.POLICY_MODES) that can act online: the planner, or the actor
# prior alone (with the executed-action noise).
ACT_MODES = ('plan', 'actor')
# Goal configurations of online training episodes: the 50 of MT1 seed `data.seed`, or a fresh one
# per episode (envs.make_env(random_goals=True)).
TRAIN_GOALS = ('mt1', 'random')
SCHEDULES = ('constant', 'linear')
# The integer fields and their least values (0 for act_dynamics_draws: the plan's draws).
_COUNTS = (('env_steps', 1), ('num_envs', 1), ('episode_steps', 1), ('checkpoint_every', 1),
           ('eval_every', 1), ('updates_per_call', 1), ('seed_steps', 0), ('schedule_steps', 0),
           ('plan_chunk', 0), ('demos', 0), ('demo_pretrain_updates', 0), ('act_num_gaussian', 0),
           ('act_iterations', 0), ('act_dynamics_draws', 0))
_HINTS = {'schedule_steps': ' (0: online.env_steps)'}


@dataclasses.dataclass(frozen=True)
class OnlineSettings(_Hashable):
  """`config.online` (field names are the section's), and the few settings of other sections that
  online training and its checks read: the model's horizon, the update's batch, the action repeat,
  the evaluation's goal splits, whether the update is data-parallel, and the training seed's task,
  seed and training goals (a seed's settings: each seed of a run has its own)."""
  enabled: bool
  init_from: str
  env_steps: int
  schedule_steps: int
  num_envs: int
  episode_steps: int
  seed_steps: int
  update_ratio: float
  updates_per_call: int
  action_noise_std: float
  prior_noise_std: float
  act_mode: str
  act_schedule: str
  act_pessimism: float
  act_pessimism_end: float
  act_disagreement: float
  act_disagreement_end: float
  act_novelty: float
  act_novelty_end: float
  act_dynamics_draws: int
  act_proposal: bool
  act_safe_selection: bool
  act_num_gaussian: int
  act_iterations: int
  exec_noise_start: float
  exec_noise_end: float
  exec_noise_corr: float
  train_goals: str
  reward: str
  demos: int
  demo_path: str
  demo_noise_std: float
  demo_share_start: float
  demo_share_end: float
  demo_pretrain_updates: int
  demo_seed_actor: bool
  plan_chunk: int
  checkpoint_every: int
  eval_every: int
  # Other sections.
  horizon: int
  batch_size: int  # config.train.batch_size
  action_repeat: int  # config.eval.action_repeat
  eval_splits: Tuple[str, ...]  # config.eval.splits
  data_parallel: bool  # config.train.data_parallel
  task: str  # config.task
  seed: int  # config.seed: the training seed
  goal_seed: int  # config.data.seed: MT1's seed of the training goals ('mt1' train_goals)

  @classmethod
  def from_config(cls, config: ml_collections.ConfigDict) -> 'OnlineSettings':
    own = {f.name: config.online[f.name] for f in dataclasses.fields(cls)
           if f.name in config.online}
    return cls(**own, horizon=config.horizon, batch_size=config.train.batch_size,
               action_repeat=config.eval.action_repeat, eval_splits=config.eval.splits,
               data_parallel=config.train.data_parallel, task=config.task, seed=config.seed,
               goal_seed=config.data.seed)

  @property
  def schedule_end(self) -> int:
    """Simulator steps at which every annealed schedule ends (the demonstrations' share, the
    executed-action noise, act_schedule='linear'): schedule_steps, or env_steps where it is 0."""
    return int(self.schedule_steps or self.env_steps)

  @property
  def decisions(self) -> int:
    """Decisions in an online episode (episode_steps at the action repeat, the last one short)."""
    return -(-self.episode_steps // self.action_repeat)

  def demo_share(self, env_steps: int) -> float:
    """Share of a batch's windows drawn from the demonstrations at `env_steps`: linear from
    `demo_share_start` at 0 to `demo_share_end` at `schedule_end`; 0 without demonstrations."""
    if not self.demos:
      return 0.0
    frac = min(max(env_steps / self.schedule_end, 0.0), 1.0)
    return float(self.demo_share_start + frac * (self.demo_share_end - self.demo_share_start))

  def demonstrations(self) -> List[demos_lib.Episode]:
    """The run's demonstrations (none when `demos` = 0), with its reward: the first successful
    episodes of `demo_path`, or the scripted policy's on `task`'s training goals (MT1 seed
    `goal_seed`, episode seeds from the training seed `seed`)."""
    if not self.demos:
      return []
    if self.demo_path:
      episodes = demos_lib.load_demos(self.demo_path, self.demos)
    else:
      episodes = demos_lib.collect_demos(self.task, self.demos, self.seed, self.goal_seed,
                                         self.action_repeat, self.episode_steps,
                                         self.demo_noise_std)
    return demos_lib.with_reward(episodes, self.reward)

  def acting_plan(self, plan: PlanSettings) -> PlanSettings:
    """The planner's settings while acting: `dataclasses.replace` of the evaluation's `plan`
    with the exploration noise on its candidates, the acting pessimism (`act_pessimism`;
    evaluation keeps `plan.pessimism`): unfamiliar states are model error offline, opportunity
    online; the acting selection (`act_safe_selection`; evaluation keeps `plan.safe_selection`;
    `plan.safe_confirm` and `plan.fallback_drop` apply while acting only with it), the search
    (`act_num_gaussian`, `act_iterations`; evaluation keeps `plan.num_gaussian` and
    `plan.iterations`), the dynamics draws (`act_dynamics_draws`, 0: the plan's) and, with
    `act_proposal` off, no proposal candidates. Under act_schedule='linear' the acting pessimism
    is no setting but the plan's traced `intrinsic` (online.schedule.ActingSchedule), so
    `pessimism` is 0 here."""
    return dataclasses.replace(
        plan, action_noise_std=self.action_noise_std, prior_noise_std=self.prior_noise_std,
        pessimism=self.act_pessimism if self.act_schedule == 'constant' else 0.0,
        safe_selection=self.act_safe_selection,
        safe_confirm=plan.safe_confirm and self.act_safe_selection,
        # The fallback hands the rest of an episode to the actor prior: a safe-selection gate too.
        fallback_drop=plan.fallback_drop if self.act_safe_selection else 0.0,
        num_gaussian=self.act_num_gaussian, iterations=self.act_iterations,
        dynamics_draws=self.act_dynamics_draws or plan.dynamics_draws,
        # Without the proposal, the first round holds the actor prior's candidates alone.
        num_candidates=(plan.num_candidates if self.act_proposal
                        else plan.num_prior_candidates))

  def check(self, model: ModelSettings, plan: PlanSettings) -> None:
    """One-line ValueErrors for online training that cannot work; `plan`: the evaluation's."""
    if model.images:
      raise ValueError('image observations (model.encoder_type=conv, dynamics_type=conv_frames) '
                       'train offline only for now: online acting does not render frames yet')
    for name, least in _COUNTS:
      v = getattr(self, name)
      if not isinstance(v, int) or isinstance(v, bool) or v < least:
        raise ValueError(f'config.online.{name} must be an integer >= {least}'
                         f'{_HINTS.get(name, "")}, got {v!r}')
    for name in ('update_ratio', 'action_noise_std', 'prior_noise_std', 'demo_noise_std'):
      if getattr(self, name) < 0:
        raise ValueError(f'config.online.{name} must be >= 0, got {getattr(self, name)}')
    self._check_demos()
    if self.decisions < self.horizon + 1:
      raise ValueError(f'config.online.episode_steps ({self.episode_steps}) gives episodes of '
                       f'{self.decisions} decisions; training windows need horizon + 1 = '
                       f'{self.horizon + 1}')
    if not self.init_from and not self.demos and self.seed_steps < 1:
      raise ValueError('config.online.seed_steps must be >= 1 from scratch (no online.init_from):'
                       ' the first updates need seed episodes')
    self.check_budget()
    self._check_loop()
    self._check_acting(model, plan)

  def _check_loop(self) -> None:
    """The reward, the update calls, the executed noise, the acting mode and the goals."""
    if self.reward not in ('dense', 'sparse'):
      raise ValueError(f"config.online.reward must be 'dense' or 'sparse', got {self.reward!r}")
    if self.updates_per_call > 1 and self.data_parallel:
      raise ValueError('config.online.updates_per_call > 1 is not supported with '
                       'config.train.data_parallel; set one of them off')
    if min(self.exec_noise_start, self.exec_noise_end) < 0:
      raise ValueError('config.online.exec_noise_start and exec_noise_end must be >= 0')
    if self.act_mode not in ACT_MODES:
      raise ValueError(f'config.online.act_mode must be one of '
                       f'{", ".join(map(repr, ACT_MODES))}, got {self.act_mode!r}')
    if self.train_goals not in TRAIN_GOALS:
      raise ValueError(f'config.online.train_goals must be one of '
                       f'{", ".join(map(repr, TRAIN_GOALS))}, got {self.train_goals!r}')
    if self.train_goals == 'random' and not self.init_from and 'train' in self.eval_splits:
      raise ValueError("config.online.train_goals='random' leaves no train goal split (each "
                       "episode draws its own goal): set config.eval.splits=held_out")
    if not 0.0 <= self.exec_noise_corr < 1.0:
      raise ValueError(f'config.online.exec_noise_corr must be in [0, 1), got '
                       f'{self.exec_noise_corr}')

  def _check_demos(self) -> None:
    """The demonstration fields (ld_mpc_jax.data.demos)."""
    for name in ('demo_share_start', 'demo_share_end'):
      if not 0.0 <= getattr(self, name) <= 1.0:
        raise ValueError(f'config.online.{name} must be in [0, 1], got {getattr(self, name)}')
    if self.demo_path and not self.demos:
      raise ValueError('config.online.demo_path is set but config.online.demos is 0: '
                       'set how many of its episodes to use')
    if self.demo_path and not os.path.isfile(self.demo_path):
      raise ValueError(f'config.online.demo_path={self.demo_path!r} is not a file')

  def check_budget(self) -> None:
    """ValueError when config.train.batch_size exceeds the windows of the first update.

    From scratch, the first update samples the seed episodes alone: the random-action waves of
    `num_envs` full-length episodes (`episode_steps` environment steps, `decisions` decisions)
    that start before `seed_steps` environment steps; each episode of D decisions holds
    D - horizon windows of horizon + 2 observations (`data.window_length`, `data.ReplayBuffer`).
    No check when no update is ever made, nor with `init_from`, whose offline dataset
    `runs.check_data_fits` checks.
    """
    if self.init_from or not self.update_ratio or self.demos:  # Demos: sampled with replacement.
      return
    wave = self.num_envs * self.episode_steps  # Environment steps per wave (success ends none).
    waves = -(-self.seed_steps // wave)
    if waves * wave >= self.env_steps:  # The run ends before its first update.
      return
    episodes = waves * self.num_envs
    windows = episodes * max(self.decisions - self.horizon, 0)
    if self.batch_size > windows:
      raise ValueError(
          f'config.train.batch_size ({self.batch_size}) is larger than the replay buffer at the '
          f'first update: {windows} windows of {self.horizon + 2} observations in {episodes} seed '
          f'episodes (config.online.seed_steps={self.seed_steps} gives {waves} wave(s) of '
          f'config.online.num_envs={self.num_envs} episodes of config.online.episode_steps='
          f'{self.episode_steps} environment steps, {self.decisions} decisions at '
          f'config.eval.action_repeat={self.action_repeat}, config.horizon={self.horizon}); '
          'lower the batch size or raise online.seed_steps')

  def _check_acting(self, model: ModelSettings, plan: PlanSettings) -> None:
    """The acting planner: its exploration settings, then its search (`act_*`)."""
    if self.act_safe_selection and plan.num_prior_candidates < 1:
      raise ValueError("config.online.act_safe_selection needs the actor prior's own sequence as "
                       'a candidate: config.plan.num_prior_candidates >= 1')
    self._check_exploration(model, plan)
    try:  # The acting planner's (validate_config checked the evaluation's).
      search.validate_plan(self.acting_plan(plan), model)
    except ValueError as err:
      raise ValueError(f'while acting (config.online.act_num_gaussian, act_iterations): '
                       f'{err}') from None
    # act_pessimism < 0 is optimism while acting: mean + |act_pessimism| std of the value
    # ensemble (annealed under act_schedule='linear', ld_mpc_jax.online.schedule).

  def _check_exploration(self, model: ModelSettings, plan: PlanSettings) -> None:
    """The acting planner's exploration settings."""
    if self.act_schedule not in SCHEDULES:
      raise ValueError(f'config.online.act_schedule must be one of {SCHEDULES}, '
                       f'got {self.act_schedule!r}')
    linear = self.act_schedule == 'linear'
    weights = (self.act_disagreement,) + ((self.act_disagreement_end,) if linear else ())
    if any(weights) and (self.act_dynamics_draws or plan.dynamics_draws) < 2:
      raise ValueError('config.online.act_disagreement needs several dynamics draws while acting '
                       'to disagree: set config.online.act_dynamics_draws >= 2')
    novelty_weights = (self.act_novelty,) + ((self.act_novelty_end,) if linear else ())
    if min(novelty_weights) < 0:
      raise ValueError('config.online.act_novelty and act_novelty_end must be >= 0, got '
                       f'{self.act_novelty} and {self.act_novelty_end}')
    if any(novelty_weights) and not model.novelty:
      raise ValueError('config.online.act_novelty needs the learned exploration value: set '
                       'config.loss.w_novelty > 0 (its loss weight) too')
    if self.act_proposal:
      return
    if not proposals.PROPOSALS.get(model.proposal_type).sequence:
      raise ValueError('config.online.act_proposal=False drops whole proposal sequences from the '
                       f'first round; proposal_type {model.proposal_type!r} has none')
    if plan.num_prior_candidates + self.act_num_gaussian < 1:
      raise ValueError('config.online.act_proposal=False leaves no candidate while acting: set '
                       'config.plan.num_prior_candidates or config.online.act_num_gaussian >= 1')
