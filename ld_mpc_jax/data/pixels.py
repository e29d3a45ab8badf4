"""Image datasets (issue 105): a state dataset's episodes replayed with image observations.

Each collected episode is replayed in its environment: the same reset seed and the same actions
give the same states (MuJoCo is deterministic; the replay checks it against the stored states),
and after every decision the camera's frame is rendered (ld_mpc_jax.envs.pixels). The image
dataset then holds the very episodes of the state dataset (actions, rewards, successes, episode
data), so that agents trained from states and from pixels learn from the same data and are
evaluated on the same held-out goals. Its observations are the flat frame stacks, stored as
uint8 (a quarter of float32's size; replay.ReplayBuffer turns the sampled windows to float32).
Rendering saves what it has every few episodes (`partial_path`): an interrupted rendering goes on
from there. With the robot's state beside the pixels (`model.proprio`), `with_proprio` appends
it from the state dataset's observations to the rendered frames (float32 then), so that one
rendering serves both.
"""

import dataclasses
import hashlib
import os
import zipfile
from typing import Optional

import numpy as np

from ld_mpc_jax import envs
from ld_mpc_jax.data import dataset as dataset_lib
from ld_mpc_jax.envs.pixels import PixelObservations, PROPRIO_INDEX, proprio_of

# Largest difference allowed between a replayed state and the stored one (float32 storage).
STATE_TOLERANCE = 1e-5


def image_path(state_path: str, size: int, frames: int, camera: str) -> str:
  """The image dataset's file beside its state dataset's."""
  stem, ext = os.path.splitext(state_path)
  return f'{stem}_px{size}x{frames}_{camera}{ext}'


def partial_path(path: str) -> str:
  """Where the rendering of the image dataset `path` keeps what it has rendered so far."""
  stem, ext = os.path.splitext(path)
  return f'{stem}.partial{ext}'


def _rendering_key(ds: dataset_lib.Dataset, size: int, frames: int, camera: str) -> str:
  """What a partial rendering was made of: the episodes' actions and seeds and the camera."""
  h = hashlib.sha256(f'{size},{frames},{camera},{ds.num_transitions}'.encode())
  for array in (ds.actions, ds.episode_starts, ds.episode_data['seed']):
    h.update(np.ascontiguousarray(array).tobytes())
  return h.hexdigest()


def _resume(path: Optional[str], key: str, obs: np.ndarray) -> int:
  """Fills `obs` with a partial rendering of the same data at `path`; returns the episodes done."""
  if not path or not os.path.exists(path):
    return 0
  try:
    with np.load(path) as f:
      if str(f['key']) != key or f['obs'].shape[1] != obs.shape[1]:
        return 0
      done, rows = int(f['episodes']), f['obs']
  except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile):  # Unreadable: start again.
    return 0
  obs[:len(rows)] = rows
  return done


def _save_partial(path: str, key: str, obs: np.ndarray, episodes: int, end: int) -> None:
  """The first `episodes` episodes' frames (rows up to `end`), replacing the file at once."""
  tmp = f'{path}.tmp.npz'
  np.savez(tmp, key=key, episodes=episodes, obs=obs[:end])
  os.replace(tmp, path)


def render_dataset(ds: dataset_lib.Dataset, size: int, frames: int, camera: str = 'corner2',
                   progress: bool = False, partial: Optional[str] = None,
                   save_every: int = 10) -> dataset_lib.Dataset:
  """`ds` (scripted episodes of one task, with their reset seeds in episode_data['seed']) with
  observations replaced by uint8 frame stacks [N, size * size * 3 frames]. Raises DatasetError
  when a replayed state departs from the stored one (another simulator, or other data).

  `partial`: a file where the frames rendered so far are saved every `save_every` episodes; a
  rendering of the same data and camera that finds it goes on from there."""
  meta = ds.metadata
  if 'seed' not in ds.episode_data or not meta.get('task'):
    raise dataset_lib.DatasetError('image datasets are rendered from collected episodes (their '
                                   'task and reset seeds); these data have none')
  env = PixelObservations(envs.make_env(meta['task'], seed=int(meta['seed']),
                                        action_repeat=int(meta['action_repeat']),
                                        max_episode_steps=int(meta['max_episode_steps'])),
                          size, frames, camera)
  obs = np.zeros((ds.observations.shape[0], env.obs_dim), np.uint8)
  key = _rendering_key(ds, size, frames, camera)
  first = _resume(partial, key, obs)
  if progress and first:
    print(f'rendering goes on after episode {first}/{ds.num_episodes} ({partial})', flush=True)
  try:
    for e in range(first, ds.num_episodes):
      start, length = int(ds.episode_starts[e]), int(ds.episode_lengths[e])
      image, info = env.reset(seed=int(ds.episode_data['seed'][e]))
      states = [info['state']]
      obs[start] = image
      for t in range(length):
        image, _, _, _, info = env.step(ds.actions[start + t])
        obs[start + t + 1] = image
        states.append(info['state'])
      gap = float(np.max(np.abs(np.asarray(states, np.float32)
                                - ds.observations[start:start + length + 1])))
      if gap > STATE_TOLERANCE:
        raise dataset_lib.DatasetError(
            f'episode {e} replays to other states (largest difference {gap:.3g}): the data were '
            'not collected with this simulator')
      if progress:
        print(f'rendered episode {e + 1}/{ds.num_episodes}', flush=True)
      if partial and (e + 1) % save_every == 0 and e + 1 < ds.num_episodes:
        _save_partial(partial, key, obs, e + 1, start + length + 1)
  finally:
    env.close()
  pixels = dict(size=int(size), frames=int(frames), camera=camera)
  return dataset_lib.Dataset(
      observations=obs, actions=ds.actions, rewards=ds.rewards, successes=ds.successes,
      episode_starts=ds.episode_starts, episode_lengths=ds.episode_lengths,
      task_ids=ds.task_ids, episode_data=ds.episode_data,
      metadata=dict(meta, obs_dim=env.obs_dim, pixels=pixels)).validate()


def get_or_render(ds: dataset_lib.Dataset, state_path: str, size: int, frames: int,
                  camera: str = 'corner2', progress: bool = True) -> dataset_lib.Dataset:
  """The cached image dataset of `ds` (saved at `state_path`), rendered and saved if missing or
  made for other data."""
  path = image_path(state_path, size, frames, camera)
  want = dict(size=int(size), frames=int(frames), camera=camera)
  if os.path.exists(path):
    cached: Optional[dataset_lib.Dataset] = dataset_lib.load(path)
    if cached.metadata.get('pixels') == want and cached.num_transitions == ds.num_transitions:
      return cached
  out = render_dataset(ds, size, frames, camera, progress=progress, partial=partial_path(path))
  dataset_lib.save(out, path)
  if os.path.exists(partial_path(path)):
    os.remove(partial_path(path))
  return out


def with_proprio(images: dataset_lib.Dataset, states: dataset_lib.Dataset) -> dataset_lib.Dataset:
  """The image dataset `images` with the robot's state (envs.pixels.PROPRIO_INDEX) of the same
  episodes' state observations (`states`, which it was rendered from) after each frame stack:
  float32 [N, pixels + 8], as PixelObservations(proprio=True) observes."""
  if images.observations.shape[0] != states.observations.shape[0]:
    raise dataset_lib.DatasetError(f'the image dataset has {images.observations.shape[0]} '
                                   f'observations, its state dataset '
                                   f'{states.observations.shape[0]}: not rendered from it')
  obs = np.concatenate([images.observations.astype(np.float32),
                        proprio_of(states.observations)], axis=-1)
  meta = dict(images.metadata, obs_dim=int(obs.shape[1]),
              pixels=dict(images.metadata['pixels'], proprio=list(PROPRIO_INDEX)))
  return dataclasses.replace(images, observations=obs, metadata=meta).validate()
