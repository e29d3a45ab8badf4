"""Goal configurations and the two evaluation splits: goals in the data, and held-out goals.

A Meta-World task has a continuous space of goal configurations (object and goal positions drawn
from a random vector). `metaworld.MT1(task, seed)` fixes 50 of them; the scripted datasets are
collected on the 50 of MT1 seed `data.seed`. Evaluation reports two splits:

* `held_out`: goals that no dataset episode starts from. Evaluation seed `s` takes the 50 goals
  of MT1 seed `HELD_OUT_MT1_SEED + s` and drops any whose goal vector matches a dataset episode's
  start (there are none in practice: the vectors are continuous random draws). So held-out goals
  are new for every evaluation seed as well.
* `train`: the goal configurations the dataset was collected on: the goals of MT1 seed
  `data.seed` whose goal vector matches a dataset episode's start.

Goals are compared by `goal_vector` (object and goal position of the noise-free first
observation), never assumed from seeds. Episode i of a split uses goal `perm[i % G]` (a
permutation of the split's G goals fixed by the evaluation seed, so 50 episodes visit 50
different goals when there are 50) and resets with seed `episode_seeds(s, n, 'eval')[i]`, which
also seeds the observation noise.
"""

import dataclasses
import functools
import hashlib
from typing import Any, List, Optional, Sequence, Tuple

import numpy as np

from ld_mpc_jax.envs import metaworld_env

SPLITS = ('held_out', 'train')
# MT1 seeds of held-out goal sets: far from the small seeds datasets are collected with.
HELD_OUT_MT1_SEED = 1_000_000
# Two goal vectors (positions in metres) are the same configuration within this distance.
MATCH_TOL = 1e-6
_SPLIT_CODE = {'held_out': 0, 'train': 1}


@dataclasses.dataclass(frozen=True)
class Episode:
  """One evaluation episode: where it starts and how it is seeded."""
  split: str  # 'held_out' or 'train'.
  index: int  # Position in its split's episode list.
  eval_seed: int  # The evaluation seed that chose it.
  reset_seed: int  # Seeds the environment reset, the observation noise and the policy's keys.
  goal_id: str  # Short hash of the goal vector.
  goal: Any = dataclasses.field(repr=False, compare=False)  # metaworld.Task to reset to.

  def record(self) -> dict:
    """The JSON-able fields of a per-episode record."""
    return dict(eval_seed=self.eval_seed, split=self.split, episode=self.index,
                reset_seed=self.reset_seed, goal_id=self.goal_id)


def goal_id(vector: np.ndarray) -> str:
  """[6] goal vector -> stable 10-hex-digit id (rounded to 0.1 mm)."""
  rounded = np.round(np.asarray(vector, np.float64), 4) + 0.0  # + 0.0 turns -0.0 into 0.0.
  return hashlib.sha1(rounded.tobytes()).hexdigest()[:10]


def dataset_goal_vectors(dataset) -> np.ndarray:
  """[E, 6]: the goal vector of every dataset episode's first observation."""
  return metaworld_env.goal_vector(dataset.observations[dataset.episode_starts])


def matches(vectors: np.ndarray, reference: np.ndarray, tol: float = MATCH_TOL) -> np.ndarray:
  """bool [N]: whether each of vectors [N, 6] is within `tol` (max-norm) of a reference [M, 6]."""
  vectors, reference = np.atleast_2d(vectors), np.atleast_2d(reference)
  if reference.shape[0] == 0:
    return np.zeros(vectors.shape[0], bool)
  dist = np.abs(vectors[:, None, :] - reference[None, :, :]).max(-1)
  return dist.min(1) <= tol


@functools.lru_cache(maxsize=16)
def mt1_goals(task: str, mt1_seed: int) -> Tuple[Tuple[Any, ...], np.ndarray]:
  """(50 metaworld.Task, goal vectors [50, 6]) of `metaworld.MT1(task, seed=mt1_seed)`.

  The vectors are read off a reset to each goal, as the environment reports them.
  """
  tasks = metaworld_env.mt1_tasks(task, int(mt1_seed))
  env = metaworld_env.make_env(task, seed=0)
  vectors = np.stack([env.reset(seed=0, options={'goal': t})[1]['goal_vector'] for t in tasks])
  env.close()
  return tasks, vectors


def split_goals(task: str, split: str, eval_seed: int, dataset_vectors: np.ndarray,
                data_mt1_seed: Optional[int]) -> Tuple[List[Any], np.ndarray]:
  """(goals, vectors [G, 6]) of a split; see the module docstring.

  Raises:
    ValueError: unknown split; a train split without the dataset's MT1 seed (data not collected
      by `ld_mpc_jax.data.collect`); or a split left empty by the goal check.
  """
  if split not in SPLITS:
    raise ValueError(f'unknown goal split {split!r}; valid: {", ".join(SPLITS)}')
  if split == 'held_out':
    tasks, vectors = mt1_goals(task, HELD_OUT_MT1_SEED + int(eval_seed))
    keep = ~matches(vectors, dataset_vectors)
  else:
    if data_mt1_seed is None:
      raise ValueError('the train goal split needs the MT1 seed the dataset was collected with')
    tasks, vectors = mt1_goals(task, int(data_mt1_seed))
    keep = matches(vectors, dataset_vectors)
  if not keep.any():
    raise ValueError(f'no {split} goals for {task} at evaluation seed {eval_seed}')
  return [t for t, k in zip(tasks, keep) if k], vectors[keep]


def make_episodes(task: str, split: str, eval_seed: int, num_episodes: int,
                  dataset_vectors: np.ndarray, data_mt1_seed: Optional[int]) -> List[Episode]:
  """The `num_episodes` episodes of one split and evaluation seed (module docstring)."""
  if num_episodes < 1:
    raise ValueError(f'num_episodes must be >= 1, got {num_episodes}')
  goals, vectors = split_goals(task, split, eval_seed, dataset_vectors, data_mt1_seed)
  perm = np.random.default_rng([int(eval_seed), _SPLIT_CODE[split], 11]).permutation(len(goals))
  seeds = metaworld_env.episode_seeds(eval_seed, num_episodes, 'eval')
  out = []
  for i in range(num_episodes):
    g = int(perm[i % len(goals)])
    out.append(Episode(split=split, index=i, eval_seed=int(eval_seed),
                       reset_seed=int(seeds[i]), goal_id=goal_id(vectors[g]), goal=goals[g]))
  return out


def episodes_for(task: str, dataset_vectors: np.ndarray, data_mt1_seed: Optional[int],
                 splits: Sequence[str], seeds: Sequence[int], num_episodes: int
                 ) -> List[Episode]:
  """Episodes of every split and evaluation seed, in that order, for `task`."""
  return [ep for split in splits for s in seeds
          for ep in make_episodes(task, split, s, num_episodes, dataset_vectors, data_mt1_seed)]
