"""What an evaluation reads of a config: `EvalSpec`, built once where an evaluation starts.

  spec = EvalSpec.from_config(config)   # the config's checks first (ActSettings.from_config)
  evaluation_suite.evaluate_checkpoint(spec, params, workdir, step, ...)

Its parts: the training goals the goal splits are drawn against (`GoalSource`), `config.eval`'s
settings (`EvalSettings`), the policies' settings (plan.modes.ActSettings) and the config's part
of an evaluation's cache key (`CacheKey`: the JSON of the sections evaluation_suite's keys hash,
as the config holds them, so that a key is byte for byte the one the config gave). A multi-task
config's spec also holds each task's own (`tasks`: `for_task`, the spec narrowed to one task, as a
config of that task alone gives it). All are frozen; the ConfigDict stays the command line's
surface and the saved `config.json`.
"""

import dataclasses
import json
from typing import Any, Dict, Tuple

import ml_collections

from ld_mpc_jax import data
from ld_mpc_jax.configs import online_enabled
from ld_mpc_jax.learn import checkpointing
from ld_mpc_jax.plan import search
from ld_mpc_jax.plan.modes import ActSettings


def key_json(value) -> str:
  """The cache key's JSON of a value (sorted keys; what JSON cannot hold, as its str)."""
  return json.dumps(value, sort_keys=True, default=str)


def without(section: dict, defaults: dict) -> dict:
  """`section` less its fields whose values equal `defaults`' (compared as JSON)."""
  return {k: v for k, v in section.items()
          if k not in defaults or key_json(v) != key_json(defaults[k])}


@dataclasses.dataclass(frozen=True)
class GoalSource:
  """The training data's goals, which the goal splits are drawn against
  (evaluation_suite.dataset_goals): the data the config trains on (`data`: its task,
  `config.data` and the action repeat the data were collected at), or online training's goals."""
  data: data.DataSpec
  # Online training from scratch (config.online without init_from), by `online.train_goals`:
  # 'random' (a fresh goal per episode) or 'mt1' (the goals of MT1 seed `data.seed`); '' for a
  # dataset's goals.
  online: str = ''

  @classmethod
  def from_config(cls, config: ml_collections.ConfigDict) -> 'GoalSource':
    online = ''
    if online_enabled(config) and not config.online.init_from:
      online = 'random' if config.online.train_goals == 'random' else 'mt1'
    return cls(data.DataSpec.from_config(config), online)

  @property
  def task(self) -> str:
    return self.data.task

  def load(self):
    """The dataset (TD-MPC2's chunk files: read once, cached by the data layer)."""
    return data.load_dataset(self.data)


_EVAL_FIELDS = ('batch_size', 'plan_chunk', 'data_parallel', 'key_seed', 'action_noise',
                'action_repeat', 'max_episode_steps', 'obs_noise', 'obs_noise_dims')


@dataclasses.dataclass(frozen=True)
class EvalSettings:
  """`config.eval`'s settings of one evaluation (configs/base.py gives each its default and
  reason), as the config holds them: the cache key hashes some of them."""
  batch_size: int
  plan_chunk: int
  data_parallel: bool
  key_seed: int
  action_noise: float
  action_repeat: int
  max_episode_steps: int
  obs_noise: float
  obs_noise_dims: str

  @classmethod
  def from_config(cls, config: ml_collections.ConfigDict) -> 'EvalSettings':
    return cls(**{f: config.eval[f] for f in _EVAL_FIELDS})

  def check(self, images: bool) -> None:
    """One-line ValueErrors for the batching, draws and noise of an evaluation of a model of
    images (`images`: ModelSettings.images) or of states."""
    for name, least in (('batch_size', 1), ('plan_chunk', 0), ('key_seed', -1)):
      v = getattr(self, name)
      if not isinstance(v, int) or isinstance(v, bool) or v < least:
        raise ValueError(f'config.eval.{name} must be an integer >= {least}, got {v!r}')
    for name in ('action_noise', 'obs_noise'):
      if not 0.0 <= float(getattr(self, name)) < float('inf'):
        raise ValueError(f'config.eval.{name} must be a std >= 0, got {getattr(self, name)!r}')
    if self.obs_noise_dims not in ('all', 'informative'):
      raise ValueError(f"config.eval.obs_noise_dims must be 'all' or 'informative', "
                       f'got {self.obs_noise_dims!r}')
    if self.obs_noise > 0 and images:
      raise ValueError('config.eval.obs_noise is noise on the state, and image observations are '
                       'rendered without it: set config.eval.obs_noise=0')


@dataclasses.dataclass(frozen=True)
class CacheKey:
  """The config's part of an evaluation's cache key (evaluation_suite._cache_key): its task and
  the JSON of `config.plan`, `config.mppi` and `config.data` as the config holds them, with the
  legacy defaults (checkpointing.legacy_defaults) that keys from version 3 leave out."""
  task: str
  plan: str
  mppi: str
  data: str
  neutral: str  # {'plan': {...}, 'data': {...}}

  @classmethod
  def from_config(cls, config: ml_collections.ConfigDict) -> 'CacheKey':
    neutral = checkpointing.legacy_defaults()
    return cls(task=config.task, plan=key_json(config.plan.to_dict()),
               mppi=key_json(config.mppi.to_dict()), data=key_json(config.data.to_dict()),
               neutral=key_json({k: neutral[k] for k in ('plan', 'data')}))

  def sections(self, version: int) -> Dict[str, Any]:
    """dict(task, plan, mppi, data) of a key of `version`: from 3 on, the plan and data fields
    at their legacy defaults left out."""
    plan, data_ = json.loads(self.plan), json.loads(self.data)
    if version >= 3:
      neutral = json.loads(self.neutral)
      plan, data_ = without(plan, neutral['plan']), without(data_, neutral['data'])
    return dict(task=self.task, plan=plan, mppi=json.loads(self.mppi), data=data_)

  def with_plan(self, **changes) -> 'CacheKey':
    """The key of the config with these `config.plan` fields changed."""
    plan = dict(json.loads(self.plan), **changes)
    return dataclasses.replace(self, plan=key_json(plan))


@dataclasses.dataclass(frozen=True)
class EvalSpec:
  """Everything an evaluation of a config reads (module docstring). Frozen and hashable."""
  goals: GoalSource
  eval: EvalSettings
  act: ActSettings
  key: CacheKey
  tasks: Tuple[Tuple[str, 'EvalSpec'], ...] = ()  # A multi-task config's (name, spec) per task.

  @classmethod
  def from_config(cls, config: ml_collections.ConfigDict) -> 'EvalSpec':
    """The spec of a config, after its checks (one-line ValueErrors)."""
    spec = cls(GoalSource.from_config(config), EvalSettings.from_config(config),
               ActSettings.from_config(config), CacheKey.from_config(config))
    # A multi-task config's tasks (config.tasks), in task-index order; () for one task.
    names = spec.goals.data.tasks
    return dataclasses.replace(spec, tasks=tuple((n, spec.for_task(n)) for n in names))

  def for_task(self, name: str) -> 'EvalSpec':
    """The single-task spec of task `name` of a multi-task spec: what an agent bound to that
    task (`tasks.bind(params, k)`) is evaluated with, equal to the spec of a config of `name`
    alone (`config.task` set, `config.tasks` removed)."""
    act = dataclasses.replace(self.act, model=dataclasses.replace(self.act.model, num_tasks=1))
    goals = dataclasses.replace(self.goals, data=self.goals.data.for_task(name))
    return dataclasses.replace(self, goals=goals, act=act,
                               key=dataclasses.replace(self.key, task=name), tasks=())

  @property
  def task(self) -> str:
    return self.goals.task

  @property
  def multitask(self) -> bool:
    """Whether the agent is task-conditioned (`tasks` holds each task's spec)."""
    return bool(self.tasks)

  @property
  def task_names(self) -> Tuple[str, ...]:
    """A multi-task spec's task names, in task-index order; () for one task."""
    return tuple(name for name, _ in self.tasks)

  def with_plan(self, **changes) -> 'EvalSpec':
    """This spec with these planner settings (`config.plan` fields) changed, checked as the
    config's (search.validate_plan); the cache key follows."""
    plan = dataclasses.replace(self.act.plan, **changes)
    search.validate_plan(plan, self.act.model)
    return dataclasses.replace(self, act=dataclasses.replace(self.act, plan=plan),
                               key=self.key.with_plan(**changes))
