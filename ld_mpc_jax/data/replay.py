"""Replay buffer of fixed-length sub-sequences that stay inside one episode."""

from typing import Dict

import numpy as np

from ld_mpc_jax.data import dataset as dataset_lib



def window_length(horizon: int) -> int:
  """Observations per training window: T = H + 1, plus one for the value bootstrap."""
  return horizon + 2

class ReplayBuffer:
  """Uniform sampler of length-T windows over a Dataset.

  A window starting at row s covers observations s .. s+T-1 and the T-1
  actions/rewards between them; it is valid iff all of it lies in one episode,
  i.e. s + T - 1 <= starts[e] + L_e for the episode e containing s. Every valid
  window is equally likely. Sampling is vectorised (one gather per array) and
  reproducible from `seed`.

  Attributes:
    dataset: the Dataset sampled from.
    seq_len: T observations per sample (the trainer uses T = H + 2).
    num_windows: number of distinct valid windows.
  """

  def __init__(self, dataset: dataset_lib.Dataset, seq_len: int, seed: int = 0,
               progress: bool = False, plans=None):
    """`plans`: optionally (plan float32 [N, H, A], planned bool [N]), each row's planned
    sequence (online.seats: the planner's at that decision) and whether it has one; windows then
    carry their first row's (`sample`)."""
    if not isinstance(seq_len, (int, np.integer)) or seq_len < 2:
      raise ValueError(
          f'seq_len must be an integer >= 2 (T observations with at '
          f'least one action between them), got {seq_len!r}.')
    self.dataset = dataset
    self.seq_len = int(seq_len)
    # Episode e offers max(L_e - T + 2, 0) start rows: starts[e] + k for
    # k = 0 .. L_e + 1 - T.
    per_episode = np.maximum(
        dataset.episode_lengths.astype(np.int64) - self.seq_len + 2, 0)
    self.num_windows = int(per_episode.sum())
    if self.num_windows == 0:
      raise ValueError(
          f'No episode is long enough for seq_len={self.seq_len}: windows need '
          f'{self.seq_len - 1} transitions, the longest episode has '
          f'{int(dataset.episode_lengths.max())}.')
    keep = per_episode > 0
    self._starts = dataset.episode_starts.astype(np.int64)[keep]
    self._cum = np.cumsum(per_episode[keep])
    self._rng = np.random.default_rng(seed)
    # Image datasets keep their uint8 frames; each sampled window becomes float32.
    obs = dataset.observations
    self._obs = obs if obs.dtype == np.uint8 else np.asarray(obs, np.float32)
    self._act = np.asarray(dataset.actions, np.float32)
    self._rew = np.asarray(dataset.rewards, np.float32)
    self._progress = progress_targets(dataset) if progress else None
    self._plans = plans

  def window_starts(self, flat: np.ndarray) -> np.ndarray:
    """Maps window indices [B] in [0, num_windows) to first rows [B]."""
    ep = np.searchsorted(self._cum, flat, side='right')
    offset = flat - np.concatenate([[0], self._cum])[ep]
    return self._starts[ep] + offset

  def sample(self, batch_size: int) -> Dict[str, np.ndarray]:
    """Draws `batch_size` windows uniformly (with replacement).

    Returns:
      dict(obs float32 [B, T, obs_dim], action float32 [B, T-1, act_dim],
      reward float32 [B, T-1]); obs[:, t] is seen before action[:, t], and
      reward[:, t] follows action[:, t]. With `progress`, also progress float32 [B, T]: each
      observation's `progress_targets`. With `plans`, also plan float32 [B, H, A] and has_plan
      float32 [B] (1.0 where the window's first row has a planned sequence) of its first row.
    """
    if not isinstance(batch_size, (int, np.integer)) or batch_size < 1:
      raise ValueError(f'batch_size must be a positive integer, got '
                       f'{batch_size!r}.')
    flat = self._rng.integers(0, self.num_windows, size=int(batch_size))
    rows = self.window_starts(flat)[:, None] + np.arange(self.seq_len)
    out = dict(obs=self._obs[rows].astype(np.float32, copy=False), action=self._act[rows[:, :-1]],
               reward=self._rew[rows[:, :-1]])
    if self._progress is not None:  # The learned progress reward's targets (loss.w_progress).
      out['progress'] = self._progress[rows]
    if self._plans is not None:  # The planner's sequences (loss.act_target='planned').
      out['plan'] = self._plans[0][rows[:, 0]]
      out['has_plan'] = self._plans[1][rows[:, 0]].astype(np.float32)
    return out

  def skip(self, batches: int, batch_size: int) -> None:
    """Advances the sampler as `batches` calls of `sample(batch_size)` would, without
    gathering the windows (one draw per call: numpy's bounded integers do not split across
    calls), so that a resumed run draws what the uninterrupted run draws next."""
    for _ in range(int(batches)):
      self._rng.integers(0, self.num_windows, size=int(batch_size))


def progress_targets(dataset: dataset_lib.Dataset) -> np.ndarray:
  """float32 [N]: each observation row's progress along its episode, the target of the learned
  progress reward (ld_mpc_jax.learn.losses): t / (t* + 1) for the t-th observation of an
  episode whose first success follows action t* (so its success state has 1), 1 after it, and
  0 on every row of an episode that never succeeds."""
  out = np.zeros(len(dataset.rewards), np.float32)
  for start, length in zip(dataset.episode_starts, dataset.episode_lengths):
    solved = np.flatnonzero(dataset.successes[start:start + length])
    if solved.size:
      t = np.arange(length + 1, dtype=np.float32)
      out[start:start + length + 1] = np.minimum(t / (solved[0] + 1), 1.0)
  return out
