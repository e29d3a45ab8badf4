"""Seeds in contiguous groups, one per device (ld_mpc_jax.ops.seed_groups)."""

import jax
import numpy as np
import pytest

from ld_mpc_jax.ops.seed_groups import SeedGroups, group_bounds


def test_groups_are_contiguous_and_as_equal_as_possible():
  assert group_bounds(5, 2) == [(0, 3), (3, 5)]
  assert group_bounds(3, 2) == [(0, 2), (2, 3)]
  assert group_bounds(4, 2) == [(0, 2), (2, 4)]
  assert group_bounds(1, 2) == [(0, 1)]  # Never an empty group.
  assert group_bounds(3, 1) == [(0, 3)]


def test_split_and_join_give_back_the_seeds_in_order():
  device = jax.local_devices()[0]
  groups = SeedGroups(3, 2, devices=[device, device])  # Two groups, here on one device.
  tree = dict(w=np.arange(12.0).reshape(3, 4), b=np.arange(3))
  parts = groups.split(tree)
  assert groups.sizes == [2, 1] and [p['w'].shape for p in parts] == [(2, 4), (1, 4)]
  joined = groups.join_host(parts)
  np.testing.assert_array_equal(joined['w'], tree['w'])
  np.testing.assert_array_equal(joined['b'], tree['b'])
  host = groups.split_host(tree)
  np.testing.assert_array_equal(host[1]['w'], tree['w'][2:])


def test_more_devices_than_the_process_has_is_one_line():
  with pytest.raises(ValueError, match='seed_devices=9 but this process has'):
    SeedGroups(9, 9)


def test_zero_means_one_device_per_seed_as_many_as_there_are():
  from ld_mpc_jax.ops.seed_groups import cpu_devices_wanted  # pylint: disable=g-import-not-at-top
  assert cpu_devices_wanted(3, 0) == 3 and cpu_devices_wanted(3, 2) == 2
  assert cpu_devices_wanted(1, 0) == 1  # One seed: JAX's default device count.
  groups = SeedGroups(3, 0, devices=jax.local_devices()[:1])
  assert groups.bounds == [(0, 3)]  # One device here: every seed on it.
