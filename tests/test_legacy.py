"""ld_mpc_jax.ops.legacy: a saved config lacking model-side fields gets the values its run used, and
only the fields it lacks."""

import ml_collections
import pytest

from ld_mpc_jax.configs import door_open
from ld_mpc_jax.ops import legacy
from ld_mpc_jax.model.settings import ModelSettings

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


def test_one_migration_keyed_by_the_config_version():
  """A config saved before `version` (version 0) runs every step to CONFIG_VERSION and gets
  the frozen values of its run; a current one is left as it is; a newer one fails in one line."""
  import json
  import ml_collections
  import pytest
  from ld_mpc_jax.configs import door_open
  current = door_open.get_config('smoke')
  assert current.version == legacy.CONFIG_VERSION
  old = json.loads(current.to_json())
  del old['version'], old['plan']['safe_margin'], old['eval']['obs_noise']
  old['objective'] = old.pop('critic')
  migrated = legacy.migrate(ml_collections.ConfigDict(old))
  assert migrated.version == legacy.CONFIG_VERSION and 'objective' not in migrated
  assert migrated.plan.safe_margin == 1.0 != current.plan.safe_margin  # The old run's value.
  assert migrated.eval.obs_noise == 0.0 and migrated.critic.value == current.critic.value
  same = legacy.migrate(ml_collections.ConfigDict(json.loads(current.to_json())))
  assert same.to_json() == current.to_json()
  newer = ml_collections.ConfigDict(dict(json.loads(current.to_json()),
                                         version=legacy.CONFIG_VERSION + 1))
  with pytest.raises(ValueError, match='newer than this code reads'):
    legacy.migrate(newer)


def test_a_version_1_config_gets_the_progress_reward_off():
  import json
  import ml_collections
  from ld_mpc_jax.configs import door_open
  from ld_mpc_jax.model import progress
  current = door_open.get_config('smoke')
  v1 = json.loads(current.to_json())
  v1['version'] = 1
  del v1['loss']['w_progress'], v1['plan']['progress_weight']
  migrated = legacy.migrate(ml_collections.ConfigDict(v1))
  assert migrated.version == legacy.CONFIG_VERSION
  assert (migrated.loss.w_progress, migrated.plan.progress_weight) == (0.0, 0.0)
  assert not ModelSettings.from_config(migrated).progress  # No head: the parameters it saved.


def test_a_version_3_online_config_keeps_its_schedules_ending_at_env_steps():
  import json
  import ml_collections
  from ld_mpc_jax import configs
  from ld_mpc_jax.configs import door_open_online
  v3 = json.loads(door_open_online.get_config('smoke').to_json())
  v3['version'] = 3
  del v3['online']['schedule_steps']
  migrated = legacy.migrate(ml_collections.ConfigDict(v3))
  assert (migrated.version, migrated.online.schedule_steps) == (legacy.CONFIG_VERSION, 0)
  assert configs.schedule_end(migrated) == migrated.online.env_steps
