"""Demonstrations as an input of online training (`online.demos`; ld_mpc_jax.runs.online).

A few successful episodes, as MoDem (Hansen et al. 2022) and DEMO3 use five: Meta-World's
scripted policy on training goals (MT1 seed `data.seed`, the goals online training uses), or the
first successful episodes of a dataset file (`online.demo_path`). They stay in their own buffer
and every batch draws a share of its windows from them, annealed linearly over the run
(ld_mpc_jax.online.settings.OnlineSettings.demo_share; MoDem: from 50% to 25%).
"""

import dataclasses
import warnings
from typing import Dict, List

import numpy as np

from ld_mpc_jax import envs
from ld_mpc_jax.data import collection
from ld_mpc_jax.data import dataset as dataset_lib

Episode = Dict[str, np.ndarray]


def with_reward(episodes: List[Episode], kind: str) -> List[Episode]:
  """Episodes with the online run's reward: 'dense' as recorded, 'sparse' = 1.0 exactly on the
  steps where the task is solved (the environment's `info['success']`), else 0.0."""
  if kind == 'dense':
    return episodes
  return [dict(ep, reward=ep['success'].astype(np.float32)) for ep in episodes]


def sparse_dataset(ds: dataset_lib.Dataset) -> dataset_lib.Dataset:
  """A copy of `ds` whose reward is 1.0 exactly on its solved steps (its success flags), as an
  online run with `online.reward='sparse'` records its own: the offline data of a sparse
  fine-tuning run (`online.init_from`)."""
  return dataclasses.replace(ds, rewards=ds.successes.astype(np.float32))


def collect_demos(task: str, num: int, seed: int, goal_seed: int, action_repeat: int,
                  episode_steps: int, noise_std: float) -> List[Episode]:
  """`num` successful episodes of the scripted policy with Gaussian action noise `noise_std`.

  Goals: the training goals of MT1 seed `goal_seed`; episode seeds: stream 'demos' of `seed`
  (each training seed its own demonstrations). Tries at most 4 x num episodes; a one-line
  DatasetError when fewer succeed. Episodes: obs [L+1, obs_dim], action [L, A], reward [L] (dense),
  success [L].
  """
  env = envs.make_env(task, seed=goal_seed, action_repeat=action_repeat,
                      max_episode_steps=episode_steps)
  policy, out = envs.scripted_policy(task), []
  with warnings.catch_warnings():
    warnings.simplefilter('ignore', UserWarning)  # Gains beyond the action range.
    for s in envs.episode_seeds(seed, 4 * num, 'demos'):
      episode = collection.run_episode(env, policy, noise_std, 0.0, int(s))
      if episode['success'].any():
        out.append(episode)
      if len(out) == num:
        break
  env.close()
  if len(out) < num:
    raise dataset_lib.DatasetError(f'config.online.demos={num}: the scripted policy of {task} succeeded in '
                     f'only {len(out)} of {4 * num} episodes of {episode_steps} environment steps')
  return out


def load_demos(path: str, num: int) -> List[Episode]:
  """The first `num` successful episodes of the dataset file `path` (one line when
  it holds fewer: DatasetError)."""
  ds = dataset_lib.load(path)
  out = [ep for ep in (ds.episode(e) for e in range(ds.num_episodes)) if ep['success'].any()]
  if len(out) < num:
    raise dataset_lib.DatasetError(f'config.online.demo_path={path!r} holds {len(out)} successful episodes; '
                     f'config.online.demos asks for {num}')
  return out[:num]


def demo_rows(batch_size: int, share: float) -> int:
  """Windows of a batch of `batch_size` drawn from the demonstrations at `share`."""
  return int(round(share * batch_size))
