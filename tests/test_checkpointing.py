"""ld_mpc_jax.checkpointing: configs saved before a field existed load with the value their run
used (migrate_config), so library code reads fields directly."""

import json

import pytest

from experiments.configs import door_open
from ld_mpc_jax import checkpointing, envs

# Fields whose fallbacks moved into migrate_config, with what a run saved before them did.
OLD_RUN_VALUES = {
    ('data', 'source'): 'metaworld', ('data', 'path'): '',
    ('data', 'max_episode_steps'): 500, ('train', 'data_parallel'): False,
    ('eval', 'data_parallel'): False, ('model', 'normalize_obs'): False,
    ('model', 'task_dim'): 96,
}


@pytest.mark.parametrize('section,name', sorted(OLD_RUN_VALUES))
def test_old_config_without_the_field_loads_with_its_run_value(tmp_path, section, name):
  raw = json.loads(door_open.get_config('smoke').to_json_best_effort())
  del raw[section][name]
  (tmp_path / checkpointing.CONFIG_FILE).write_text(json.dumps(raw))
  config = checkpointing.load_config(str(tmp_path))
  assert config[section][name] == OLD_RUN_VALUES[section, name]


def test_saved_config_round_trips(tmp_path):
  config = door_open.get_config('smoke')
  checkpointing.save_config(config, str(tmp_path))
  loaded = checkpointing.load_config(str(tmp_path))
  assert json.loads(loaded.to_json_best_effort()) == json.loads(config.to_json_best_effort())


def test_old_runs_scripted_source_is_the_suites():
  assert OLD_RUN_VALUES['data', 'source'] == envs.SUITE.name
  assert OLD_RUN_VALUES['data', 'max_episode_steps'] == envs.MAX_EPISODE_STEPS
