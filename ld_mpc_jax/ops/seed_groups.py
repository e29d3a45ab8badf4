"""Training seeds spread over devices (`config.train.seed_devices`): the seeds of a run in
contiguous groups, one group per device, each group's arrays on its device and its programs
dispatched separately, so that the devices compute at the same time.

Why separate programs and not one sharded `jit`: on a CPU split into virtual devices
(`jax_num_cpu_devices`), an SPMD program sharded along the seed axis ran no faster than on one
device, while independent programs on two devices ran concurrently (a vmapped 8-layer MLP,
batch 64: 2 seeds cost 1.02x one seed on 2 devices, 1.92x on one; docs/sparse.md). The seeds
never communicate, so nothing is lost by keeping them apart. With one device there is one
group and every call is the one-device program of before.
"""

from typing import Any, Dict, List, Optional, Sequence, Tuple

import jax
import numpy as np


def group_bounds(num_seeds: int, num_groups: int) -> List[Tuple[int, int]]:
  """[start, stop) of each of min(num_groups, num_seeds) contiguous groups, sizes as equal as
  possible, the larger ones first: (5, 2) -> [(0, 3), (3, 5)]."""
  num_groups = max(1, min(num_groups, num_seeds))
  base, extra = divmod(num_seeds, num_groups)
  bounds, start = [], 0
  for g in range(num_groups):
    stop = start + base + (g < extra)
    bounds.append((start, stop))
    start = stop
  return bounds


def cpu_devices_wanted(num_seeds: int, seed_devices: int) -> int:
  """The virtual CPU devices a run asks for before JAX starts (`jax_num_cpu_devices`; 1: leave
  JAX's default): `seed_devices`, or with 0 one per seed."""
  return num_seeds if seed_devices == 0 else seed_devices


@jax.jit
def _unstack(tree: Any) -> List[Any]:
  """A tree with a leading seed axis -> one tree per seed."""
  n = jax.tree_util.tree_leaves(tree)[0].shape[0]
  return [jax.tree_util.tree_map(lambda x, i=i: x[i], tree) for i in range(n)]


class SeedGroups:
  """`num_seeds` seeds over the first `num_devices` local devices (fewer when there are fewer
  seeds; 0: one per seed, as many as this process has). Trees with a leading seed axis are held
  as one tree per group (`split`, `split_host`); `per_seed` and `join_host` gather them back."""

  def __init__(self, num_seeds: int, num_devices: int = 1,
               devices: Optional[Sequence[jax.Device]] = None):
    devices = list(jax.local_devices() if devices is None else devices)
    if num_devices == 0:
      num_devices = min(num_seeds, len(devices))
    if min(num_devices, num_seeds) > len(devices):
      raise ValueError(f'config.train.seed_devices={num_devices} but this process has '
                       f'{len(devices)} device(s); on a CPU the train command makes that many '
                       f'(jax_num_cpu_devices) before JAX starts')
    self.bounds = group_bounds(num_seeds, num_devices)
    self.devices = devices[:len(self.bounds)]

  def __len__(self) -> int:
    return len(self.bounds)

  @property
  def sizes(self) -> List[int]:
    return [stop - start for start, stop in self.bounds]

  def split(self, tree: Any) -> List[Any]:
    """A tree with a leading seed axis [num_seeds, ...] (host or device arrays) -> one tree per
    group [group size, ...], placed on the group's device. One group: the tree, placed."""
    if len(self) == 1:
      return [jax.device_put(tree, self.devices[0])]
    return [jax.device_put(jax.tree_util.tree_map(lambda x: x[a:b], tree), d)
            for (a, b), d in zip(self.bounds, self.devices)]

  def split_host(self, tree: Dict[str, np.ndarray]) -> List[Dict[str, np.ndarray]]:
    """Host arrays [num_seeds, ...] -> each group's slices (numpy views; no copy)."""
    return [{k: v[a:b] for k, v in tree.items()} for a, b in self.bounds]

  def per_seed(self, trees: Sequence[Any]) -> List[Any]:
    """The groups' stacked trees -> one tree per seed, in seed order (one jitted slicing per
    group size and device)."""
    return [tree for group in trees for tree in _unstack(group)]

  def join_host(self, trees: Sequence[Any]) -> Any:
    """The groups' trees -> one host tree [num_seeds, ...] (numpy; waits for the devices)."""
    host = [jax.device_get(t) for t in trees]
    return jax.tree_util.tree_map(lambda *xs: np.concatenate(xs, axis=0), *host)
