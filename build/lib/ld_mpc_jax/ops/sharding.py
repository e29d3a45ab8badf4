"""Data parallelism with `jax.sharding`: a 1-D mesh over the devices, the batch split along it.

The training state (parameters, optimiser state, EMA) is replicated on every device and each
device computes the loss on its slice of the batch; XLA's SPMD partitioner inserts the gradient
all-reduce. The same update function serves any device count, one included. With several
processes (`jax.distributed.initialize`, docs/scaling.md), `jax.devices()` lists every
process's devices, each process samples its share of the batch and `shard_batch` assembles the
global batch from the shares.
"""

from typing import Any, Dict, Optional, Sequence

import jax
from jax.sharding import Mesh, NamedSharding, PartitionSpec
import numpy as np

BATCH_AXIS = 'batch'


def make_mesh(devices: Optional[Sequence[jax.Device]] = None) -> Mesh:
  """1-D mesh with axis 'batch' over `devices` (default: all devices of all processes)."""
  devices = jax.devices() if devices is None else list(devices)
  return Mesh(np.asarray(devices), (BATCH_AXIS,))


def replicated(mesh: Mesh) -> NamedSharding:
  """Every device holds the whole array."""
  return NamedSharding(mesh, PartitionSpec())


def batch_sharded(mesh: Mesh) -> NamedSharding:
  """Leading (batch) axis split over the mesh; other axes whole."""
  return NamedSharding(mesh, PartitionSpec(BATCH_AXIS))


def local_batch_size(batch_size: int, mesh: Mesh) -> int:
  """This process's share of a global batch of `batch_size` examples.

  Raises:
    ValueError: `batch_size` is not a multiple of the number of devices.
  """
  if batch_size % mesh.size:
    raise ValueError(f'config.train.batch_size ({batch_size}) must be a multiple of the number '
                     f'of devices ({mesh.size}) for data-parallel training')
  return batch_size // jax.process_count()


def replicate(tree: Any, mesh: Mesh) -> Any:
  """A pytree of arrays placed whole on every device of `mesh`."""
  return jax.device_put(tree, replicated(mesh))


def shard_batch(batch: Dict[str, np.ndarray], mesh: Mesh) -> Dict[str, jax.Array]:
  """This process's host arrays [B_local, ...] -> global arrays [B, ...] split along the batch.

  With one process B = B_local and this is a device_put with the batch sharding.
  """
  sharding = batch_sharded(mesh)
  return {k: jax.make_array_from_process_local_data(sharding, np.asarray(v))
          for k, v in batch.items()}


def unreplicate(tree: Any) -> Any:
  """Replicated arrays -> their copy on this process's first local device (for evaluation)."""
  return jax.tree_util.tree_map(
      lambda x: x.addressable_data(0) if isinstance(x, jax.Array) else x, tree)
