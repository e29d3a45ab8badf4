"""The replay buffer of an online run (ld_mpc_jax.runs.online): the offline dataset (if any), the
online episodes, and the demonstrations in their own buffer (ld_mpc_jax.data.demos)."""

import os
from typing import Any, Dict, List, Optional, Tuple

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
  carry the learned progress reward's targets (`replay.progress_targets`). With `plan_shape` (H, A)
  (`loss.act_target='planned'`), an episode the planner acted in also has plan [L, H, A], its
  chosen sequence at each decision, and every window carries its first row's (zeros and has_plan 0
  where there is none: offline data, demonstrations, random or actor waves).
  """

  def __init__(self, seq_len: int, offline: Optional[dataset_lib.Dataset], seed: int,
               demos: Optional[List[Episode]] = None, progress: bool = False,
               plan_shape: Optional[Tuple[int, int]] = None):
    self.seq_len, self.offline, self.progress = seq_len, offline, progress
    self.plan_shape = plan_shape
    self.episodes: List[Episode] = []
    self.demos = list(demos or [])
    self.rng = np.random.default_rng([seed, 23])
    self._sampler = None
    self._demo_sampler = (ReplayBuffer(dataset_lib.Dataset.from_episodes(self.demos), seq_len,
                                       seed=self.rng, progress=progress,
                                       plans=self._flat_plans(self.demos))
                          if self.demos else None)

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
                                   self.seq_len, seed=self.rng, progress=self.progress,
                                   plans=self._flat_plans(old + self.episodes))
    return self._sampler

  def _flat_plans(self, episodes: List[Episode]):
    """(plan [N, H, A], planned [N]) of the episodes' rows as a Dataset lays them out (each
    episode's L + 1 rows; zeros and False where an episode has no plans), or None without
    `plan_shape`."""
    if self.plan_shape is None:
      return None
    plan, planned = [], []
    for ep in episodes:
      n, p = len(ep['action']), ep.get('plan')
      plan.append(np.zeros((n + 1,) + self.plan_shape, np.float32) if p is None else
                  np.concatenate([p, np.zeros((1,) + self.plan_shape, np.float32)]))
      planned.append(np.arange(n + 1) < (0 if p is None else n))
    return np.concatenate(plan), np.concatenate(planned)

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
    extra = None
    if self.plan_shape is not None:  # Online episodes all have one length: [E, L, H, A].
      planned = np.array(['plan' in ep for ep in self.episodes])
      if len({len(ep['action']) for ep in self.episodes}) > 1:
        raise ValueError('planned sequences are saved for episodes of one length only')
      zeros = np.zeros((len(self.episodes[0]['action']),) + self.plan_shape, np.float32)
      extra = dict(planned=planned, plan=np.stack([ep.get('plan', zeros)
                                                   for ep in self.episodes]))
    dataset_lib.save(dataset_lib.Dataset.from_episodes(self.episodes, metadata=meta,
                                                       episode_data=extra), path)

  def load(self, path: str) -> Dict[str, Any]:
    """Replaces the online episodes and the sampler state with `path`'s; returns its counters."""
    ds = dataset_lib.load(path)
    self.episodes = [ds.episode(e) for e in range(ds.num_episodes)]
    if 'planned' in ds.episode_data:
      for ep, planned, plan in zip(self.episodes, ds.episode_data['planned'],
                                   ds.episode_data['plan']):
        if planned:
          ep['plan'] = np.asarray(plan, np.float32)
    self.rng.bit_generator.state = ds.metadata['sampler_rng']
    self._sampler = None
    return ds.metadata['online']
