"""Shared fixtures (the smoke-sized config: tiny widths, 2 diffusion steps) and test-speed settings.

Compilation dominates the suite's time on a CPU, so before JAX is imported:
- XLA compiles without most optimisations (half the compile time of the smoke update step; the
  tiny test models run fast either way);
- one persistent compilation cache for the session, shared by the pytest-xdist workers and by
  the subprocesses that tests launch (a killed-and-resumed run compiles once).
Both are environment variables, so a user's own settings win.
"""

import atexit
import ctypes.util
import os
import shutil
import tempfile

os.environ.setdefault('JAX_DISABLE_MOST_OPTIMIZATIONS', '1')
if 'JAX_COMPILATION_CACHE_DIR' not in os.environ:  # The xdist controller creates it.
  _cache_dir = tempfile.mkdtemp(prefix='ld_mpc_jax_tests_xla_')
  os.environ['JAX_COMPILATION_CACHE_DIR'] = _cache_dir
  atexit.register(shutil.rmtree, _cache_dir, ignore_errors=True)
os.environ.setdefault('JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS', '0')
os.environ.setdefault('JAX_PERSISTENT_CACHE_MIN_ENTRY_SIZE_BYTES', '0')

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
