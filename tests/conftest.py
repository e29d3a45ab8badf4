"""Shared fixtures (the smoke-sized config: tiny widths, 2 diffusion steps) and test-speed settings.

Compilation dominates the suite's time on a CPU, so before JAX is imported:
- XLA compiles without most optimisations (half the compile time of the smoke update step; the
  tiny test models run fast either way);
- XLA's elemental CPU emitters (faster to compile than its fusion emitters);
- one persistent compilation cache for the session, shared by the pytest-xdist workers and by
  the subprocesses that tests launch (a killed-and-resumed run compiles once);
- the tests marked `long` (end-to-end, left out of the default run by pyproject.toml's addopts;
  `-m long` or `-m ""` runs them) start first, so that no xdist worker is left running one
  alone at the end.
The XLA settings are environment variables, so a user's own settings win.
"""

import atexit
import ctypes.util
import fcntl
from importlib import metadata
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
# XLA's elemental CPU emitters compile the smoke update step about a third faster than its
# fusion emitters (7.5-8.5 s against 10.5-12.7 s). Only with the jaxlib this was measured with:
# XLA aborts on a flag it does not know.
if metadata.version('jaxlib').startswith('0.10.') and 'XLA_FLAGS' not in os.environ:
  os.environ['XLA_FLAGS'] = '--xla_cpu_use_fusion_emitters=false'

# Offscreen MuJoCo rendering: use OSMesa where the library is installed (rendering tests skip
# with a reason otherwise). Must be set before mujoco is imported.
if ctypes.util.find_library('OSMesa'):
  os.environ.setdefault('MUJOCO_GL', 'osmesa')

import jax
import pytest

from ld_mpc_jax.configs import door_open


@pytest.fixture
def smoke_config():
  return door_open.get_config('smoke')


@pytest.fixture
def smoke_params(smoke_config):
  from ld_mpc_jax import init_params
  return init_params(smoke_config, jax.random.key(0))


@pytest.fixture(scope='session')
def build_once(tmp_path_factory):
  """build_once(name, build) -> path: runs build(path) once in this test session, whichever
  pytest-xdist worker asks first; the others wait for it and share the result. (A module-scoped
  fixture runs once per worker that runs a test of the module, so with --dist worksteal two
  workers each trained the same runs.)"""
  base = tmp_path_factory.getbasetemp()
  # Under xdist, the session's folder (every worker's basetemp is a folder in it).
  root = base.parent if os.environ.get('PYTEST_XDIST_WORKER') else base

  def once(name, build):
    path = root / f'shared_{name}'
    with open(root / f'shared_{name}.lock', 'w') as lock:
      fcntl.flock(lock, fcntl.LOCK_EX)  # Released when the file closes, also on a failure.
      if not (path / '.built').exists():  # Else another worker built it.
        shutil.rmtree(path, ignore_errors=True)
        path.mkdir()
        build(path)
        (path / '.built').touch()
    return path

  return once


def pytest_collection_modifyitems(items):
  items.sort(key=lambda item: item.get_closest_marker('long') is None)  # Stable: else as found.
