"""What one training seed's run reads of the config, read once: `SeedPlan`, frozen.

  plans = seed_plans(config, workdir)  # One per training seed.
  check_workdirs(plans, continue_with_changes)  # A WorkdirError before anything is written.
  runs.Run(plans[0]); train_seeds.train_seeds(plans, ...); online.train_online(plans, workdir)

`runs.train.train_and_evaluate(config, workdir)`, the training entry, is the one place in runs/
that reads the config: it validates it, checks the workdir and builds the plans; `Run`, the jobs,
`train_seeds`, `train_online` and the checks of `online.init_from` read the plans alone. A seed's
plan holds the text of the config.json its run records (its own config: seed config.seed + i,
`train.num_seeds` 1, `online.init_from` its own offline seed's), so each seed of a run of several
saves in <workdir>/seed<seed> what a run of that seed alone saves.
"""

import dataclasses
import json
import os
from typing import Any, Dict, Optional, Tuple

import ml_collections

from ld_mpc_jax.configs import online_enabled
from ld_mpc_jax.configs.overrides import with_overrides
from ld_mpc_jax.data.sources import DataSpec
from ld_mpc_jax.envs.tasks import Tasks
from ld_mpc_jax.eval.spec import EvalSpec
from ld_mpc_jax.learn import checkpointing
from ld_mpc_jax.learn.train_state import LearnSettings
from ld_mpc_jax.online.settings import OnlineSettings


@dataclasses.dataclass(frozen=True)
class LoopSettings:
  """`config.train`'s fields of the training loop, and the training seed (`config.seed`: the
  parameters', data order's and update keys' seed)."""
  seed: int
  num_steps: int
  batch_size: int
  log_every: int
  checkpoint_every: int
  eval_every: int
  max_checkpoints: int
  seed_devices: int
  data_parallel: bool


@dataclasses.dataclass(frozen=True)
class EvalRounds:
  """`config.eval`'s fields of a run's evaluations: episodes per goal split and evaluation seed
  of the final one (0: no evaluation), of each periodic one (the planner on held-out goals, on
  the first evaluation seed), the evaluation seeds, the goal splits and the other policies of the
  final evaluation."""
  episodes: int
  periodic_episodes: int
  seeds: Tuple[int, ...]
  splits: Tuple[str, ...]
  baselines: Tuple[str, ...]

  @classmethod
  def from_fields(cls, e: Dict[str, Any]) -> 'EvalRounds':
    """From `config.eval` as a plain dict (its `to_dict()`)."""
    return cls(e['episodes'], e['periodic_episodes'], tuple(e['seeds']), tuple(e['splits']),
               tuple(e['baselines']))

  def check(self) -> None:
    """One-line ValueErrors for the policies, episodes and goal splits (the policies' names are
    checked against agent.POLICY_MODES by runs.Run)."""
    if not all(isinstance(m, str) for m in self.baselines):
      raise ValueError('config.eval.baselines must name policy modes, got '
                       f'{list(self.baselines)}')
    if self.episodes < 0:
      raise ValueError('config.eval.episodes must be >= 0 (0 skips evaluation), got '
                       f'{self.episodes}')
    if set(self.splits) - {'held_out', 'train'} or not self.splits:
      raise ValueError('config.eval.splits must name held_out and/or train, got '
                       f'{list(self.splits)}')


_LOOP_FIELDS = tuple(f.name for f in dataclasses.fields(LoopSettings) if f.name != 'seed')


@dataclasses.dataclass(frozen=True)
class SeedPlan:
  """Everything one training seed's run reads (module docstring): its run directory, the text of
  the config.json it records, and its settings."""
  workdir: str
  config_json: str  # Its config, as config.json holds it (checkpointing.save_config).
  learn: LearnSettings
  eval: EvalSpec
  data: DataSpec
  tasks: Tasks
  loop: LoopSettings
  evals: EvalRounds
  online: Optional[OnlineSettings] = None  # Where configs.online_enabled.

  @property
  def seed(self) -> int:
    return self.loop.seed

  @property
  def task(self) -> str:
    return self.data.task

  def fields(self) -> Dict[str, Any]:
    """The recorded config as nested dicts (as JSON holds it: sequences as lists)."""
    return json.loads(self.config_json)


def seed_plans(config: ml_collections.ConfigDict, workdir: str) -> Tuple[SeedPlan, ...]:
  """Each training seed's plan (online or offline): the run itself with one seed; with
  `train.num_seeds` = N > 1, seeds config.seed + i in <workdir>/seed<seed>, each config as a
  separate run of that seed would save it (num_seeds = 1; `online.init_from`: `seed_source`).
  """
  seeds = [(config, workdir)]
  if config.train.num_seeds > 1:
    seeds = []
    for i in range(config.train.num_seeds):
      c = with_overrides(config, {'seed': config.seed + i, 'train.num_seeds': 1})
      if 'online' in c and c.online.init_from:  # Each seed fine-tunes from its own offline seed.
        c.online.init_from = seed_source(c.online.init_from, c.seed)
      seeds.append((c, os.path.join(workdir, f'seed{c.seed}')))
  return tuple(SeedPlan(
      workdir=w, config_json=c.to_json_best_effort(indent=2), learn=LearnSettings.from_config(c),
      eval=EvalSpec.from_config(c), data=DataSpec.from_config(c), tasks=Tasks.from_config(c),
      loop=LoopSettings(seed=c.seed, **{f: c.train[f] for f in _LOOP_FIELDS}),
      evals=EvalRounds.from_fields(c.eval.to_dict()),
      online=OnlineSettings.from_config(c) if online_enabled(c) else None) for c, w in seeds)


def check_workdirs(plans: Tuple[SeedPlan, ...], continue_with_changes: bool = False) -> None:
  """Each seed's workdir against the config its plan records (`checkpointing.check_workdir`: a
  WorkdirError, before anything is written, when it holds a run of another config)."""
  for p in plans:
    checkpointing.check_workdir(p.fields(), p.learn, p.workdir, continue_with_changes)


def seed_source(path: str, seed: int) -> str:
  """The offline run a training seed fine-tunes from: <path>/seed<seed> when `path` is a run of
  several seeds (no config of its own, a folder per seed), else `path` itself."""
  own = os.path.join(path, f'seed{seed}')
  if not os.path.exists(os.path.join(path, checkpointing.CONFIG_FILE)) and os.path.isdir(own):
    return own
  return path
