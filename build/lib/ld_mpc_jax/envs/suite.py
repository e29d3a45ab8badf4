"""The environment suite interface, and the registry of suites.

A suite is what data collection, evaluation and online acting need of a family of tasks: an
environment factory, its task names, its goal splits, a scripted policy per task, and the
observation and action sizes. `ld_mpc_jax.envs` registers Meta-World as the one suite today.
"""

import dataclasses
from typing import Any, Callable, List, Tuple

from ld_mpc_jax.ops.registry import Registry


@dataclasses.dataclass(frozen=True)
class Suite:
  """One family of tasks behind a gymnasium factory.

  Attributes:
    name: the registry key; also the name of its scripted data source (`config.data.source`).
    make_env: make_env(task, seed, action_repeat=2, max_episode_steps=..., obs_noise_std=0.0,
      terminate_on_success=False, render_mode=None, image_size=...) -> an environment with
      observations [obs_dim] and actions [act_dim] in [-1, 1]; `step` reports info['success'],
      info['env_steps'] and info['substeps'], `reset(seed=s, options={'goal': g})` starts at a
      goal of `make_episodes`.
    task_names: () -> the task names.
    check_task: task -> task, or a one-line ValueError listing the valid names.
    scripted_policy: task -> policy(obs [obs_dim]) -> action [act_dim] (float32).
    episode_seeds: (seed, num_episodes, stream) -> int64 [num_episodes] reset seeds of
      independent streams ('eval', 'collect', 'online').
    goal_splits: the names of its goal splits (held-out goals first).
    make_episodes: (task, split, eval_seed, num_episodes, dataset goal vectors [E, G],
      the data's goal seed or None) -> the episodes of one split (`goals.Episode`).
    dataset_goal_vectors: dataset -> [E, G] goal vectors of its episodes' starts.
    train_goals: (task, seed) -> (goals, vectors [M, G]): the goals episodes start from when
      collected (or acted online) with `seed`.
    obs_dim, act_dim: observation and action sizes.
    max_episode_steps: its own episode limit, in environment steps.
    packages: installed packages whose versions shape its data (the simulator's suite first).
    scripted_source: the dataset metadata 'source' of episodes collected with its policies.
  """
  name: str
  make_env: Callable[..., Any]
  task_names: Callable[[], List[str]]
  check_task: Callable[[str], str]
  scripted_policy: Callable[[str], Callable]
  episode_seeds: Callable[..., Any]
  goal_splits: Tuple[str, ...]
  make_episodes: Callable[..., List[Any]]
  dataset_goal_vectors: Callable[[Any], Any]
  train_goals: Callable[[str, int], Tuple[Any, Any]]
  obs_dim: int
  act_dim: int
  max_episode_steps: int
  packages: Tuple[str, ...]
  scripted_source: str


SUITES = Registry('environment suite')
