"""Shared fixtures: the smoke-sized config (tiny widths, 2 diffusion steps)."""

import os

os.environ.setdefault('XLA_FLAGS', '--xla_force_host_platform_device_count=1')

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
