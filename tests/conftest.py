"""Shared fixtures: the smoke-sized config (tiny widths, 2 diffusion steps)."""

import ctypes.util
import os

# Offscreen MuJoCo rendering: use OSMesa where the library is installed (rendering tests skip
# with a reason otherwise). Must be set before mujoco is imported.
if ctypes.util.find_library('OSMesa'):
  os.environ.setdefault('MUJOCO_GL', 'osmesa')

import jax
import pytest

from experiments.configs import door_open


@pytest.fixture
def smoke_config():
  return door_open.get_config('smoke')


@pytest.fixture
def smoke_params(smoke_config):
  from ld_mpc_jax import init_params
  return init_params(smoke_config, jax.random.key(0))
