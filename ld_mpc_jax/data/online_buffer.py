"""The replay buffer of an online run (ld_mpc_jax.runs.online): the offline dataset (if any), the
online episodes, and the demonstrations in their own buffer (ld_mpc_jax.data.demos)."""

import os
from typing import Any, Dict, List, Optional

import numpy as np

from ld_mpc_jax.data import dataset as dataset_lib
from ld_mpc_jax.data import demos as demos_lib
from ld_mpc_jax.data.replay import ReplayBuffer

BUFFER_DIR = 'online'
Episode = Dict[str, np.ndarray]


def buffer_path(workdir: str, step: int) -> str:
  return os.path.join(workdir, BUFFER_DIR, f'buffer_{step}.npz')


class Buffer:
  """Episodes are dicts of obs [L+1, obs_dim], action [L, A], reward [L], success [L] (float32,
  bool). Windows are sampled uniformly over the offline data and the online episodes
  (`ReplayBuffer`), and a share of each batch uniformly over the demonstrations, with one
  persistent generator, whose state the checkpoint keeps. The demonstrations are not saved:
  they are drawn again, the same, from the config (`OnlineSettings.demonstrations`). With `progress`, windows
  carry the learned progress reward's targets (`replay.progress_targets`).
  """

  def __init__(self, seq_len: int, offline: Optional[dataset_lib.Dataset], seed: int,
               demos: Optional[List[Episode]] = None, progress: bool = False):
    self.seq_len, self.offline, self.progress = seq_len, offline, progress
    self.episodes: List[Episode] = []
    self.demos = list(demos or [])
    self.rng = np.random.default_rng([seed, 23])
    self._sampler = None
    self._demo_sampler = (ReplayBuffer(dataset_lib.Dataset.from_episodes(self.demos), seq_len,
                                       seed=self.rng, progress=progress) if self.demos else None)

  def add(self, episodes: List[Episode]) -> None:
    self.episodes.extend(episodes)
    self._sampler = None

  @property
  def has_main(self) -> bool:
    """Whether windows can come from outside the demonstrations (offline data or episodes)."""
    return self.offline is not None or bool(self.episodes)

  def _main(self) -> ReplayBuffer:
    if self._sampler is None:
      old = [self.offline.episode(e) for e in range(self.offline.num_episodes)] if (
          self.offline is not None) else []
      # default_rng(Generator) is that generator: the sampler draws from self.rng.
      self._sampler = ReplayBuffer(dataset_lib.Dataset.from_episodes(old + self.episodes),
                                   self.seq_len, seed=self.rng, progress=self.progress)
    return self._sampler

  def sample(self, batch_size: int, groups: int = 1, demo_share: float = 0.0
             ) -> Dict[str, np.ndarray]:
    """`groups` batches of `batch_size` windows, concatenated [groups x batch_size, ...]; in
    each, `demos.demo_rows(batch_size, demo_share)` windows come from the demonstrations (all of
    them while there is nothing else), the rest from the offline data and online episodes;
    with demonstrations, 'demo' [groups x batch_size] is 1.0 on their windows, else 0.0."""
    if self._demo_sampler is None:
      return self._main().sample(batch_size * groups)
    d = batch_size if not self.has_main else demos_lib.demo_rows(batch_size, demo_share)
    parts = []
    if batch_size - d:
      parts.append(self._main().sample(groups * (batch_size - d)))
    if d:
      parts.append(self._demo_sampler.sample(groups * d))
    for part, flag in zip(parts, ([0.0] if batch_size - d else []) + ([1.0] if d else [])):
      part['demo'] = np.full(len(part['obs']), flag, np.float32)
    per_group = lambda x: x.reshape((groups, -1) + x.shape[1:])
    return {k: np.concatenate([per_group(p[k]) for p in parts], axis=1).reshape(
        (groups * batch_size,) + parts[0][k].shape[1:]) for k in parts[0]}

  def save(self, path: str, counters: Dict[str, Any]) -> None:
    """Online episodes and `counters` to `path` (.npz, atomic; `dataset.save`)."""
    meta = dict(online=counters, sampler_rng=self.rng.bit_generator.state)
    dataset_lib.save(dataset_lib.Dataset.from_episodes(self.episodes, metadata=meta), path)

  def load(self, path: str) -> Dict[str, Any]:
    """Replaces the online episodes and the sampler state with `path`'s; returns its counters."""
    ds = dataset_lib.load(path)
    self.episodes = [ds.episode(e) for e in range(ds.num_episodes)]
    self.rng.bit_generator.state = ds.metadata['sampler_rng']
    self._sampler = None
    return ds.metadata['online']
