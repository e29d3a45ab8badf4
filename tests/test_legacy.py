"""ld_mpc_jax.ops.legacy: a saved config lacking model-side fields gets the values its run used, and
only the fields it lacks."""

import ml_collections
import pytest

from experiments.configs import door_open
from ld_mpc_jax.ops import legacy

# What a run saved before these fields existed did (hand-written, not read from legacy).
OLD_RUN_VALUES = {
    ('model', 'proposal_type'): 'diffusion_seq', ('model', 'dynamics_type'): 'diffusion_ar',
    ('model', 'normalize_obs'): False, ('model', 'normalize_dynamics'): False,
    ('model', 'task_dim'): 96, ('loss', 'w_consistency'): 0.0, ('loss', 'w_q'): 0.0,
    ('loss', 'w_v'): 0.0,
}


def test_fill_adds_only_the_missing_fields():
  c = ml_collections.ConfigDict(dict(model=dict(width=8, normalize_obs=True)))
  legacy.fill(c, 'model', dict(width=256, normalize_obs=False, task_dim=96))
  assert c.model.to_dict() == dict(width=8, normalize_obs=True, task_dim=96)


@pytest.mark.parametrize('section,name', sorted(OLD_RUN_VALUES))
def test_a_missing_model_field_gets_its_old_run_value(section, name):
  raw = door_open.get_config('smoke').to_dict()
  del raw[section][name]
  config = legacy.fill_model_fields(ml_collections.ConfigDict(raw))
  assert config[section][name] == OLD_RUN_VALUES[section, name]


def test_every_field_of_the_table_is_filled_and_nothing_else_changes():
  new = door_open.get_config('smoke')
  raw = new.to_dict()
  for section, fields in legacy.MODEL_FIELDS.items():
    for name in fields:
      del raw[section][name]
  old = legacy.fill_model_fields(ml_collections.ConfigDict(raw)).to_dict()
  for section, fields in legacy.MODEL_FIELDS.items():
    for name, value in fields.items():
      assert old[section][name] == value, (section, name)
      old[section][name] = new[section][name]
  assert old == new.to_dict()
  # A current config is left as it is.
  assert legacy.fill_model_fields(door_open.get_config('smoke')).to_dict() == new.to_dict()
