"""Mixed-quality offline data from Meta-World's scripted policies.

Each episode runs a task's scripted expert (`envs.scripted_policy`) with one
noise level: the expert's action gets Gaussian noise of std `noise_std`, and
with probability `random_prob` per decision it is replaced by a uniform random
action in [-1, 1]^4; the result is clipped to [-1, 1]. Episodes run the full
length (`max_episode_steps` environment steps; success does not end them) with
the env factory's action repeat, and record per-step success flags.

Presets (D4RL-like; the levels are data, see PRESETS):
  expert: the scripted policy with a little noise.
  medium: heavier noise and many random actions.
  weak:   mostly random actions, no near-expert episode.
  mixed:  a quarter each of four levels, from expert-like to mostly random.
"""

import json
import os
import time
import warnings
from typing import Any, Callable, Dict, Optional, Sequence

import numpy as np
import tqdm

from ld_mpc_jax.data import dataset as dataset_lib
from ld_mpc_jax import envs

# Each level: Gaussian action-noise std, per-decision probability of a uniform
# random action, and the fraction of the preset's episodes at that level.
PRESETS: Dict[str, Sequence[Dict[str, float]]] = {
    'expert': (dict(noise_std=0.1, random_prob=0.0, fraction=1.0),),
    'medium': (dict(noise_std=0.5, random_prob=0.65, fraction=1.0),),
    # No near-expert episode: every decision is noisy and 85% are random (door-open: 15% of
    # 20 episodes succeed by chance, docs/data.md).
    'weak': (dict(noise_std=1.0, random_prob=0.85, fraction=1.0),),
    'mixed': (
        dict(noise_std=0.1, random_prob=0.0, fraction=0.25),
        dict(noise_std=0.5, random_prob=0.5, fraction=0.25),
        dict(noise_std=1.0, random_prob=0.75, fraction=0.25),
        dict(noise_std=1.0, random_prob=0.9, fraction=0.25),  # mostly random
    ),
}


# Bumped whenever collected data change for the same request: cached files of an older collector
# are collected again. 2: observations are no longer shifted in place by the scripted policies
# of door-open and button-press (which moved the stored object position).
COLLECTOR_VERSION = 2


def check_preset(preset: str, name: str = 'preset') -> None:
  """One-line ValueError naming `name` when `preset` is not one of PRESETS."""
  if preset not in PRESETS:
    raise ValueError(f'unknown {name} {preset!r}; valid: {sorted(PRESETS)}')


def level_assignment(preset: str, episodes: int, seed: int) -> np.ndarray:
  """int64 [episodes]: the PRESETS level index of each episode (shuffled)."""
  check_preset(preset)
  fractions = np.array([lvl['fraction'] for lvl in PRESETS[preset]])
  counts = np.floor(fractions * episodes).astype(np.int64)
  remainder = fractions * episodes - counts
  counts[np.argsort(-remainder)[:episodes - counts.sum()]] += 1
  levels = np.repeat(np.arange(len(counts)), counts)
  return np.random.default_rng([int(seed), 7]).permutation(levels)


def run_episode(env, policy: Callable[[np.ndarray], np.ndarray],
                noise_std: float, random_prob: float, seed: int
                ) -> Dict[str, np.ndarray]:
  """One noisy scripted episode until termination or truncation.

  Returns:
    dict(obs [L+1, obs_dim], action [L, act_dim], reward [L], success [L]).
  """
  rng = np.random.default_rng(int(seed))
  obs, _ = env.reset(seed=int(seed))
  act_dim = env.action_space.shape[0]
  observations, actions, rewards, successes = [obs], [], [], []
  done = False
  while not done:
    action = np.asarray(policy(obs), np.float64)
    action = action + noise_std * rng.standard_normal(act_dim)
    if rng.random() < random_prob:
      action = rng.uniform(-1.0, 1.0, act_dim)
    action = np.clip(action, -1.0, 1.0).astype(np.float32)
    obs, reward, terminated, truncated, info = env.step(action)
    observations.append(obs)
    actions.append(action)
    rewards.append(reward)
    successes.append(bool(info['success']))
    done = terminated or truncated
  return dict(obs=np.stack(observations), action=np.stack(actions),
              reward=np.asarray(rewards, np.float32),
              success=np.asarray(successes, bool))


def collect(task: str, preset: str, episodes: int, seed: int = 0,
            action_repeat: int = 2,
            max_episode_steps: int = envs.MAX_EPISODE_STEPS,
            progress: bool = True) -> dataset_lib.Dataset:
  """Collects `episodes` noisy scripted episodes of `task` at `preset`.

  Args:
    task: Meta-World v3 task name.
    preset: key of PRESETS ('expert', 'medium', 'weak', 'mixed').
    episodes: number of episodes.
    seed: MT1 seed of the environment (its 50 goal configurations) and base of
      the per-episode seeds (stream 'collect' of `episode_seeds`).
    action_repeat: as in `make_env`; recorded in the metadata.
    max_episode_steps: episode length in environment steps.
    progress: show a tqdm progress bar.

  Returns:
    A validated Dataset; metadata and per-episode noise/seed in episode_data.
  """
  envs.check_task(task)
  if episodes < 1:
    raise ValueError(f'episodes must be >= 1, got {episodes}')
  levels = level_assignment(preset, episodes, seed)
  seeds = envs.episode_seeds(seed, episodes, 'collect')
  env = envs.make_env(task, seed=seed, action_repeat=action_repeat,
                      max_episode_steps=max_episode_steps)
  policy = envs.scripted_policy(task)
  spec = PRESETS[preset]
  out, start = [], time.time()
  bar = tqdm.tqdm(range(episodes), desc=f'collect {task}/{preset}',
                  disable=not progress)
  with warnings.catch_warnings():
    # The scripted policies warn that their gains exceed the action range.
    warnings.simplefilter('ignore', UserWarning)
    for i in bar:
      lvl = spec[levels[i]]
      out.append(run_episode(env, policy, lvl['noise_std'],
                             lvl['random_prob'], seeds[i]))
      bar.set_postfix(success=np.mean([ep['success'].any() for ep in out]))
  env.close()
  episode_data = dict(
      level=levels.astype(np.int64),
      noise_std=np.array([spec[l]['noise_std'] for l in levels]),
      random_prob=np.array([spec[l]['random_prob'] for l in levels]),
      seed=seeds)
  metadata: Dict[str, Any] = dict(
      source=envs.SUITE.scripted_source, collector_version=COLLECTOR_VERSION, task=task, tasks=[task],
      preset=preset,
      levels=[dict(l) for l in spec], episodes=int(episodes), seed=int(seed),
      action_repeat=int(action_repeat),
      max_episode_steps=int(max_episode_steps),
      obs_dim=envs.OBS_DIM, act_dim=envs.ACT_DIM,
      versions=dataset_lib.package_versions(),
      collection_seconds=round(time.time() - start, 2))
  return dataset_lib.Dataset.from_episodes(
      out, metadata=metadata, episode_data=episode_data)


def dataset_path(data_dir: str, task: str, preset: str, episodes: int,
                 seed: int, action_repeat: int,
                 max_episode_steps: int = envs.MAX_EPISODE_STEPS) -> str:
  """Cache file name of a collected dataset (episodes shorter than Meta-World's: `_T<steps>`)."""
  steps = ('' if max_episode_steps == envs.MAX_EPISODE_STEPS
           else f'_T{max_episode_steps}')
  return os.path.join(
      data_dir, f'{task}_{preset}_{episodes}ep_seed{seed}_ar{action_repeat}{steps}.npz')


def get_or_collect(task: str, preset: str, episodes: int, seed: int,
                   data_dir: str, action_repeat: int = 2,
                   max_episode_steps: int = (
                       envs.MAX_EPISODE_STEPS),
                   progress: bool = True) -> dataset_lib.Dataset:
  """Loads the cached dataset if present and valid, else collects and saves it.

  A cached file that fails validation (e.g. NaN), or whose metadata does not match the request,
  is never overwritten: it is renamed with a `.bad` suffix (a warning says so), then the data
  are collected again.
  """
  path = dataset_path(data_dir, task, preset, episodes, seed, action_repeat, max_episode_steps)
  want = dict(collector_version=COLLECTOR_VERSION, task=task, preset=preset, episodes=episodes,
              seed=seed,
              action_repeat=action_repeat, max_episode_steps=max_episode_steps)
  if os.path.exists(path):
    try:
      ds = dataset_lib.load(path)
      got = {k: ds.metadata.get(k) for k in want}
      if got == want:
        return ds
      _set_aside(path, f'{path} holds {got}, not {want}')
    except dataset_lib.DatasetError as err:
      _set_aside(path, f'invalid cached dataset ({err})')  # err names the file.
  ds = collect(task, preset, episodes, seed=seed, action_repeat=action_repeat,
               max_episode_steps=max_episode_steps, progress=progress)
  dataset_lib.save(ds, path)
  return ds


def _set_aside(path: str, reason: str) -> str:
  """Renames `path` to <path>.bad (or <path>.<n>.bad, never replacing one) with a warning."""
  bad, n = f'{path}.bad', 1
  while os.path.exists(bad):
    bad, n = f'{path}.{n}.bad', n + 1
  os.replace(path, bad)
  warnings.warn(f'{reason}: moved to {bad}; collecting again')
  return bad


def summary(ds: dataset_lib.Dataset) -> Dict[str, Optional[float]]:
  """Episode/transition counts, success rate and mean return of a dataset."""
  return dict(episodes=ds.num_episodes, transitions=ds.num_transitions,
              success_rate=float(ds.episode_success().mean()),
              mean_return=float(ds.episode_returns().mean()))


def success_per_level(ds: dataset_lib.Dataset) -> Dict[str, Optional[float]]:
  """Episode success rate of a collected dataset at each of its preset's noise levels (None
  for a level without episodes: JSON null, not NaN, which is no JSON).

  Keys are the levels as JSON (noise_std, random_prob, fraction).
  """
  out = {}
  for j, lvl in enumerate(PRESETS[ds.metadata['preset']]):
    sel = ds.episode_data['level'] == j
    out[json.dumps(lvl)] = float(ds.episode_success()[sel].mean()) if sel.any() else None
  return out
