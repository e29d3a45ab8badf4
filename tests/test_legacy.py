"""ld_mpc_jax.ops.legacy: a saved config (the loaded config.json, plain dicts) lacking fields gets
the values its run used, and only the fields it lacks; every saved config migrates as it did."""

import copy
import hashlib
import json
import os

import ml_collections
import pytest

from ld_mpc_jax.configs import door_open
from ld_mpc_jax.learn import checkpointing
from ld_mpc_jax.ops import legacy
from ld_mpc_jax.model.settings import ModelSettings

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# What a run saved before these fields existed did (hand-written, not read from legacy).
OLD_RUN_VALUES = {
    ('model', 'proposal_type'): 'diffusion_seq', ('model', 'dynamics_type'): 'diffusion_ar',
    ('model', 'normalize_obs'): False, ('model', 'normalize_dynamics'): False,
    ('model', 'task_dim'): 96, ('loss', 'w_consistency'): 0.0, ('loss', 'w_q'): 0.0,
    ('loss', 'w_v'): 0.0,
}


def test_fill_adds_only_the_missing_fields():
  c = dict(model=dict(width=8, normalize_obs=True))
  legacy.fill(c, 'model', dict(width=256, normalize_obs=False, task_dim=96))
  assert c['model'] == dict(width=8, normalize_obs=True, task_dim=96)


@pytest.mark.parametrize('section,name', sorted(OLD_RUN_VALUES))
def test_a_missing_model_field_gets_its_old_run_value(section, name):
  raw = door_open.get_config('smoke').to_dict()
  del raw[section][name]
  config = legacy.fill_model_fields(raw)
  assert config[section][name] == OLD_RUN_VALUES[section, name]


def test_every_field_of_the_table_is_filled_and_nothing_else_changes():
  new = door_open.get_config('smoke')
  raw = new.to_dict()
  for section, fields in legacy.MODEL_FIELDS.items():
    for name in fields:
      del raw[section][name]
  old = legacy.fill_model_fields(raw)
  for section, fields in legacy.MODEL_FIELDS.items():
    for name, value in fields.items():
      assert old[section][name] == value, (section, name)
      old[section][name] = new[section][name]
  assert old == new.to_dict()
  # A current config is left as it is.
  assert legacy.fill_model_fields(new.to_dict()) == new.to_dict()


def test_one_migration_keyed_by_the_config_version():
  """A config saved before `version` (version 0) runs every step to CONFIG_VERSION and gets
  the frozen values of its run; a current one is left as it is; a newer one fails in one line."""
  current = door_open.get_config('smoke')
  assert current.version == legacy.CONFIG_VERSION
  old = json.loads(current.to_json())
  del old['version'], old['plan']['safe_margin'], old['eval']['obs_noise']
  old['objective'] = old.pop('critic')
  as_saved = copy.deepcopy(old)
  migrated = legacy.migrate(old)
  assert type(migrated) is dict and old == as_saved  # A new dict; what was saved stays.
  assert migrated['version'] == legacy.CONFIG_VERSION and 'objective' not in migrated
  assert migrated['plan']['safe_margin'] == 1.0 != current.plan.safe_margin  # The old run's.
  assert migrated['eval']['obs_noise'] == 0.0
  assert migrated['critic']['value'] == current.critic.value
  same = legacy.migrate(json.loads(current.to_json()))
  assert ml_collections.ConfigDict(same).to_json() == current.to_json()
  newer = dict(json.loads(current.to_json()), version=legacy.CONFIG_VERSION + 1)
  with pytest.raises(ValueError, match='newer than this code reads'):
    legacy.migrate(newer)
  with pytest.raises(TypeError, match='as a dict, not a ConfigDict'):
    legacy.migrate(current)


def test_a_version_1_config_gets_the_progress_reward_off():
  current = door_open.get_config('smoke')
  v1 = json.loads(current.to_json())
  v1['version'] = 1
  del v1['loss']['w_progress'], v1['plan']['progress_weight']
  migrated = checkpointing.migrate_config(v1)
  assert migrated.version == legacy.CONFIG_VERSION
  assert (migrated.loss.w_progress, migrated.plan.progress_weight) == (0.0, 0.0)
  assert not ModelSettings.from_config(migrated).progress  # No head: the parameters it saved.


def test_a_version_3_online_config_keeps_its_schedules_ending_at_env_steps():
  from ld_mpc_jax import configs
  from ld_mpc_jax.configs import door_open_online
  v3 = json.loads(door_open_online.get_config('smoke').to_json())
  v3['version'] = 3
  del v3['online']['schedule_steps']
  migrated = checkpointing.migrate_config(v3)
  assert (migrated.version, migrated.online.schedule_steps) == (legacy.CONFIG_VERSION, 0)
  assert configs.schedule_end(migrated.online) == migrated.online.env_steps


# What migrating each saved config gave, to version 7, when the migration still worked on a
# ConfigDict (captured from that code before it moved to plain dicts): (digest of its to_dict()
# with the type of every value, digest of the config.json it saves again). The steps are frozen,
# so these never change.
FROZEN_AT = 7
SAVED = {
    'results/obs_space/door_medium_8149f3e/config_seed0.json':
        ('b73bdd9df809ebc1', 'a7a9f159179f7adf'),
    'results/online_door/seed2_novelty_cf3ef98/config_run.json':
        ('f2253c617856f2ff', 'fbd0fa29f9da7b04'),
    'results/online_pick/dense_3seeds_227620e/config_seed0.json':
        ('29f374e85f1c62f6', '57d560610c1f38a7'),
    'results/records/confirm_m1_h200/config_door_weak_seed0.json':
        ('1d7f7394965c2a98', '7aa1b7db2036374f'),
    'results/records/confirm_m1_h200/config_door_weak_seed1.json':
        ('7d7dbde208ab303e', '6a52e7e0557bcb70'),
    'results/records/confirm_m1_h200/config_door_weak_seed2.json':
        ('9df558e70c06ce71', '7c6b4f6a35d06cfe'),
    'results/records/confirm_m1_h200/config_reach_medium_seed0.json':
        ('9a69f2497ad12b55', 'aa0ee9d38832c483'),
    'results/records/confirm_m1_h200/config_reach_medium_seed1.json':
        ('8ecf7e2eb30e7fb2', 'ab1cfef736630792'),
    'results/records/confirm_m1_h200/config_reach_medium_seed2.json':
        ('46e195a5ad4b9c84', '9f41e3a3daec01d2'),
    'results/records/door_medium_confirm/config_seed0.json':
        ('c4b49202264e8bdc', 'b4dcf005e6de7880'),
    'results/records/door_medium_confirm/config_seed1.json':
        ('b58d0df6fcf2c453', '49bcc1b948aac34e'),
    'results/records/door_medium_confirm/config_seed2.json':
        ('ff89085459e02be3', '2d1c5d2d3f4dd88a'),
    'results/records/door_open_leave_one_out/no_discount_seed0/config.json':
        ('2823b6e77beaf4ee', '483c293937261a8e'),
    'results/records/door_open_leave_one_out/no_episode_shape_seed0/config.json':
        ('5504b42406806bdc', '5a78ce3b43e7d8fa'),
    'results/records/door_open_leave_one_out/no_exec_noise_seed0/config.json':
        ('a1fa67c906c80634', 'feac74e1ea6a6f7f'),
    'results/records/door_open_leave_one_out/no_update_ratio_seed0/config.json':
        ('3de43ff5dbda2352', 'fc3035750e031ba9'),
    'results/records/door_open_leave_one_out/no_update_ratio_seed1/config.json':
        ('806921e42a984849', '05416aaf4b076d2c'),
    'results/records/door_open_tanh_sparse/config.json': ('996d52e66de2b1e2', 'bc524a04ee16fa9a'),
    'results/records/door_open_tanh_timed/config.json': ('29a6bb286f8ba2cb', 'cc4e6ce0f145a315'),
    'results/records/door_open_weak_confirm/config_seed0.json':
        ('1d7f7394965c2a98', '7aa1b7db2036374f'),
    'results/records/door_open_weak_confirm/config_seed1.json':
        ('7d7dbde208ab303e', '6a52e7e0557bcb70'),
    'results/records/door_open_weak_confirm/config_seed2.json':
        ('9df558e70c06ce71', '7c6b4f6a35d06cfe'),
    'results/records/mt10_confirm/config_seed0.json': ('c0efdb79019c8a90', '3e61c24c6c5e513c'),
    'results/records/mt10_confirm/config_seed1.json': ('74a742f534cb39a9', '279878ac04ff05dc'),
    'results/records/mt10_confirm/config_seed2.json': ('d00e618b1927a327', 'ed8b221974158674'),
    'results/records/push_medium_confirm/config_seed0.json':
        ('ebaf062e7e6e619b', '2dd27df1abb171b0'),
    'results/records/push_medium_confirm/config_seed1.json':
        ('8dccdc954832d0d8', '24855f3875eb9c40'),
    'results/records/push_medium_confirm/config_seed2.json':
        ('06371351cb02846b', 'e5f57eefd0c52e9f'),
    'results/sparse_door_open/balance_4a48b82/config_seed0.json':
        ('20a304addf05afcf', '94fb6d2de36ab33c'),
    'results/sparse_door_open/no_act_safe_f7e1db3/config_seed0.json':
        ('184feaf26c988fb8', '73fb109e3efb4e6e'),
    'results/sparse_door_open/no_actor_bc_f7e1db3/config_seed0.json':
        ('e8183e77b2cb92cf', 'be6a708417b8d651'),
    'results/sparse_door_open/no_seed_actor_f7e1db3/config_seed0.json':
        ('2c29c758c28a8391', '3548b3ff62f36b04'),
    'results/sparse_door_open/noprop_fc00832/config_seed0.json':
        ('ace3b15d762a406f', 'c4c335639a44e91b'),
    'results/sparse_door_open/obs_novelty_2f9d53c_rerun/config_seed0.json':
        ('13e26c3fb65279ca', '7548325c507de027'),
    'results/sparse_door_open/v1_planner_search_463d416/config_seed0.json':
        ('d6fd6b74f3ea37f3', '2d88b65fcb32d5a9'),
    'results/sparse_door_open/v3_bc_actor_safe_22ad14c/config_seed0.json':
        ('146fc7d2df5cfd95', '4c28305f841c0816'),
    'results/sparse_pick_place/v3_5demos_3b9bf74/config_seed0.json':
        ('ea01e6c51c1acefb', '4d2614a1392b361f'),
    'results/sparse_pick_place/v3_5demos_60k_3b9bf74/config_seed0.json':
        ('c300defc2a362e94', '24162aae0c941a05'),
    'results/sparse_push/balance_100k_8de5a31/config_seed0.json':
        ('1da0d86c273016c8', 'a4a740aae896f20e'),
    'results/sparse_push/dense_5demos_251e821/config_seed0.json':
        ('dba314bfe1e65100', 'abeb6b72f3a77411'),
    'tests/golden/door_open_smoke/config.json': ('fd9681ec0acaf858', '0abfdcdc993d4235'),
}
# Hand-written saved configs of the cases the committed ones lack, with what they gave.
SYNTHETIC = {
    'v0_objective_online': dict(
        model=dict(width=8, task_dim=32), objective=dict(value='expectile', hidden=[64, 64]),
        loss=dict(w_q=1.0), eval=dict(splits=['train']), data=dict(), train=dict(),
        plan=dict(pessimism=0.5, safe_selection=True, num_gaussian=3, iterations=2),
        online=dict(env_steps=1000)),
    'v0_no_critic': dict(model=dict(), loss=dict(), eval=dict(), plan=dict(), data=dict(),
                         train=dict()),
    'v0_objective_and_critic': dict(
        objective=dict(value='x'), critic=dict(value='y'), model=dict(), loss=dict(),
        eval=dict(), plan=dict(), data=dict(), train=dict()),
    'v2_online': dict(version=2, model=dict(), loss=dict(), plan=dict(), online=dict()),
    'v4_offline': dict(version=4, model=dict(novelty_target='obs')),
    'v7': dict(version=7, model=dict(), anything=[1, (2, 3)]),
}
SYNTHETIC_DIGESTS = {
    'v0_objective_online': ('014c1f93f5b45a8f', 'a1507be2aadfc03b'),
    'v0_no_critic': ('1bcb115b481a7152', '72f0849aa9b0e337'),
    'v0_objective_and_critic': ('c6b21d8475314091', '6b74552f44fdb5d3'),
    'v2_online': ('0f18154d3bd04592', '9bb615f81b004b00'),
    'v4_offline': ('50963f4693924ca8', '0f480a3bc4177ec2'),
    'v7': ('8c7d8d4ff3b05e6f', 'b988a10ee5b35e73'),
}


def _typed(x):
  """`x` as JSON that keeps every value's type (a tuple is not a list, 1 is not 1.0 or True)."""
  if isinstance(x, dict):
    return {'dict': [[k, _typed(v)] for k, v in sorted(x.items())]}
  if isinstance(x, (list, tuple)):
    return {type(x).__name__: [_typed(v) for v in x]}
  return [type(x).__name__, x]


def _digests(config: ml_collections.ConfigDict) -> tuple:
  typed = hashlib.sha256(json.dumps(_typed(config.to_dict())).encode()).hexdigest()[:16]
  saved = hashlib.sha256(config.to_json_best_effort(indent=2).encode()).hexdigest()[:16]
  return typed, saved


@pytest.mark.parametrize('path', sorted(SAVED))
def test_each_saved_config_migrates_as_it_did(path, tmp_path, monkeypatch):
  if not os.path.exists(os.path.join(ROOT, path)):
    pytest.skip(f'{path} is no longer in the repository')
  monkeypatch.setattr(legacy, 'CONFIG_VERSION', FROZEN_AT)  # Steps added later are not these.
  with open(os.path.join(ROOT, path)) as f:
    raw = json.load(f)
  (tmp_path / checkpointing.CONFIG_FILE).write_text(json.dumps(raw))
  loaded = checkpointing.load_config(str(tmp_path))  # As on load: migrated, then a ConfigDict.
  assert _digests(loaded) == SAVED[path]
  assert loaded.to_dict() == legacy.migrate(raw)


@pytest.mark.parametrize('name', sorted(SYNTHETIC))
def test_each_hand_written_saved_config_migrates_as_it_did(name, monkeypatch):
  monkeypatch.setattr(legacy, 'CONFIG_VERSION', FROZEN_AT)
  raw = copy.deepcopy(SYNTHETIC[name])
  assert _digests(checkpointing.migrate_config(raw)) == SYNTHETIC_DIGESTS[name]
  assert raw == SYNTHETIC[name]  # What was saved is left as it is.
