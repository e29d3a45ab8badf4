"""Behaviour pinned across refactors: a checkpoint written by earlier code still loads, and for a
fixed key it gives the same decisions (tests/golden/make_golden.py wrote the fixtures)."""

import shutil

import jax
import numpy as np
import pytest

from ld_mpc_jax.configs import door_open
from ld_mpc_jax.learn import checkpointing, train_state
from tests.golden import make_golden

EXPECTED = dict(np.load(make_golden.PLANS))


def _check(prefix: str, got: dict) -> None:
  for name, value in got.items():
    want = EXPECTED[f'{prefix}_{name}']
    if name.endswith('info'):  # The fixture predates the fourth field (the fallback's state).
      np.testing.assert_array_equal(value[..., :want.shape[-1]], want, err_msg=f'{prefix} {name}')
      np.testing.assert_array_equal(value[..., want.shape[-1]:], -1)  # No fallback configured.
    else:
      np.testing.assert_allclose(value, want, atol=1e-4, err_msg=f'{prefix} {name}')


def test_old_smoke_checkpoint_loads_and_plans_the_same(tmp_path):
  workdir = tmp_path / 'run'
  shutil.copytree(make_golden.SMOKE_DIR, workdir)
  config, params, step = checkpointing.load_for_evaluation(str(workdir))
  assert step == 0
  _check('smoke', make_golden.decisions(config, params))


def test_cpu_preset_plans_the_same():
  config = door_open.get_config('cpu')
  learn = train_state.LearnSettings.from_config(config)
  params = train_state.create_train_state(learn, jax.random.key(0)).ema_params
  _check('cpu', make_golden.decisions(config, params))


def test_the_fixture_can_tell_a_change():
  """Another key gives other plans: equal decisions above are not an accident of the fixture."""
  config = door_open.get_config('smoke')
  learn = train_state.LearnSettings.from_config(config)
  params = train_state.create_train_state(learn, jax.random.key(1)).ema_params
  with pytest.raises(AssertionError):
    _check('smoke', make_golden.decisions(config, params))
