"""ld_mpc_jax.ops.sharding on this process's one device. (The 2-device update and planner, in
subprocesses: tests/e2e/test_sharding_two_devices.py.)"""

import jax
import numpy as np
import pytest

from ld_mpc_jax.ops import sharding


def test_batch_must_split_evenly_over_devices():
  mesh = sharding.make_mesh()
  assert sharding.local_batch_size(8, mesh) == 8 // jax.process_count()
  two = jax.sharding.Mesh(np.array(jax.devices() * 2), ('batch',))  # Stands in for 2 devices.
  with pytest.raises(ValueError, match=r'batch_size \(7\) must be a multiple of the number of '
                     r'devices \(2\)'):
    sharding.local_batch_size(7, two)
