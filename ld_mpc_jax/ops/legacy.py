"""The one migration of saved configs, keyed by the config's version (`config.version`).

Library code reads config fields directly (defaults live in ld_mpc_jax/configs/base.py); a
saved config is brought up to date once, on load (checkpointing.migrate_config -> `migrate`):
each step of STEPS above the version it was saved with runs in order. A migration works on
what was saved, the loaded config.json as nested plain dicts ({section: {field: value}}); the
ConfigDict is built from its result, once, by checkpointing.migrate_config. Version 0 is every
config saved before the field existed (until 2026-11-29): `to_v1` renames its old sections and fills
the fields it lacks with the values that mean what its run did (the tables below, frozen: they
never change, or old runs would change with them). A change that must read older configs
differently raises CONFIG_VERSION and adds its step; a new field whose default changes nothing
needs no step (a config of the previous version is filled with it by the step that adds it).
This module is the one place old names are understood; elsewhere they are errors naming the new
one (`renamed_hint`).
"""

import copy

# Old section name -> new: `objective` held the critic settings; J itself lives in
# ld_mpc_jax/model/objective.py, so the word names J alone.
RENAMED_SECTIONS = {'objective': 'critic'}
# The critic settings of a run saved before they existed (as config.objective): the behaviour
# value of the sequence objective, a BC actor, no latent rollouts in the loss.
LEGACY_CRITIC = dict(value='behaviour', actor='bc', latent_rollout=False, num_values=1,
                     num_q=2, hidden=(256, 256), expectile=0.7, value_scale=100.0,
                     awr_temperature=1.0, awr_max_weight=100.0, rollout_steps=1,
                     td_target='one_step', entropy_coef=1e-4, log_std_map='clip')
# section -> {field: value for runs saved before it existed}.
MODEL_FIELDS = {
    'model': dict(proposal_type='diffusion_seq', dynamics_type='diffusion_ar',
                  normalize_obs=False, normalize_dynamics=False, task_dim=96,
                  obs_mask_constant=False),
    'critic': dict(td_target='one_step', entropy_coef=1e-4, log_std_map='clip',
                   rollout_unroll=True),
    'loss': dict(w_consistency=0.0, w_q=0.0, w_v=0.0, w_demo_bc=0.0, w_noise_inv=0.0,
               reward_balance=0.0),
}
TASK_DIM = MODEL_FIELDS['model']['task_dim']  # Before it was a field (TD-MPC2's width).
# Evaluation, planner, data and training settings of configs saved before they existed; the
# values mean what those runs did (no pessimism before `plan.pessimism`, no search, no gates;
# the scripted Meta-World data with 500-step episodes; one device, one seed, no noise).
FIELDS = {
    'eval': dict(splits=('held_out', 'train'), seeds=(0,), batch_size=50, plan_chunk=0,
                 baselines=('actor', 'proposal'), data_parallel=False, key_seed=-1,
                 action_noise=0.0, obs_noise=0.0, obs_noise_dims='all'),
    'plan': dict(pessimism=0.0, dynamics_draws=1, guidance_scale=0.0, guidance_dynamics_steps=1,
                 num_gaussian=0, gaussian_std=2.0, iterations=0, num_refine=64, num_elites=8,
                 temperature=0.5, min_std=0.05, selection='argmax', safe_selection=False,
                 safe_margin=1.0, safe_margin_scaling='none', safe_confirm=False,
                 confirm_draws=1, confirm_margin=-1.0, fallback_drop=0.0, fallback_floor=0.0,
                 first_round=('proposal', 'gaussian'), latent_filter=0.0),
    'data': dict(source='metaworld', path='', max_episode_steps=500),
    'train': dict(data_parallel=False, num_seeds=1, obs_noise_aug=0.0, seed_devices=1),
}
# The version ld_mpc_jax/configs/base.py writes (config.version).
CONFIG_VERSION = 11


def _online_fields(saved: dict) -> dict:
  """Online runs saved before acting had its own settings: acting as evaluation did (the
  `saved` config's plan section, filled)."""
  p = saved['plan']
  return dict(act_pessimism=p['pessimism'], exec_noise_start=0.0, exec_noise_end=0.0,
              exec_noise_corr=0.0, updates_per_call=1, reward='dense', act_mode='plan',
              act_safe_selection=p['safe_selection'], train_goals='mt1',
              act_num_gaussian=p['num_gaussian'], act_iterations=p['iterations'], demos=0,
              demo_path='', demo_noise_std=0.1, demo_share_start=0.5, demo_share_end=0.25,
              demo_pretrain_updates=0, demo_seed_actor=False, act_schedule='constant',
              act_pessimism_end=0.0, act_disagreement=0.0, act_disagreement_end=0.0,
              act_dynamics_draws=0, act_proposal=True)


def to_v1(saved: dict) -> None:
  """Version 0 -> 1 (in place): old section names renamed, then every field above filled."""
  rename_sections(saved)  # Before the fills, which use the new names.
  fill_model_fields(saved)
  for section, fields in FIELDS.items():
    fill(saved, section, fields)
  if 'online' in saved:
    fill(saved, 'online', _online_fields(saved))


# Fields added in version 2, with the values that change nothing (the learned progress reward).
V2_FIELDS = {'loss': dict(w_progress=0.0), 'plan': dict(progress_weight=0.0)}


def to_v2(saved: dict) -> None:
  """Version 1 -> 2 (in place): the learned progress reward's fields, off."""
  for section, fields in V2_FIELDS.items():
    fill(saved, section, fields)


# Fields added in version 3, with the values that change nothing (the exploration value).
V3_FIELDS = {'loss': dict(w_novelty=0.0), 'model': dict(novelty_members=5)}
V3_ONLINE_FIELDS = dict(act_novelty=0.0, act_novelty_end=0.0)


def to_v3(saved: dict) -> None:
  """Version 2 -> 3 (in place): the learned exploration value's fields, off."""
  for section, fields in V3_FIELDS.items():
    fill(saved, section, fields)
  if 'online' in saved:
    fill(saved, 'online', V3_ONLINE_FIELDS)


# Field added in version 4, with the value that changes nothing: the schedules end at env_steps.
V4_ONLINE_FIELDS = dict(schedule_steps=0)


def to_v4(saved: dict) -> None:
  """Version 3 -> 4 (in place): `online.schedule_steps`, 0 (the schedules end at env_steps)."""
  if 'online' in saved:
    fill(saved, 'online', V4_ONLINE_FIELDS)


# Field added in version 5, with the value that changes nothing: the novelty members predict the
# next latent.
V5_FIELDS = {'model': dict(novelty_target='latent')}


def to_v5(saved: dict) -> None:
  """Version 4 -> 5 (in place): `model.novelty_target`, 'latent'."""
  for section, fields in V5_FIELDS.items():
    fill(saved, section, fields)


# Field added in version 6, with the value that changes nothing: the learned MLP encoder.
V6_FIELDS = {'model': dict(encoder_type='mlp')}


def to_v6(saved: dict) -> None:
  """Version 5 -> 6 (in place): `model.encoder_type`, 'mlp'."""
  for section, fields in V6_FIELDS.items():
    fill(saved, section, fields)


# Fields added in version 7, read only by the pixel kinds: the image shape of flat image
# observations (64 x 64 RGB).
V7_FIELDS = {'model': dict(image_size=64, image_channels=3)}


def to_v7(saved: dict) -> None:
  """Version 6 -> 7 (in place): `model.image_size` 64 and `model.image_channels` 3."""
  for section, fields in V7_FIELDS.items():
    fill(saved, section, fields)


# Fields added in version 8, with the values that change nothing (the TD-MPC2 control's
# options): RMS-normalised latents, scalar V and Q heads.
V8_FIELDS = {'model': dict(latent_norm='rms'), 'critic': dict(heads='scalar')}


def to_v8(saved: dict) -> None:
  """Version 7 -> 8 (in place): `model.latent_norm` 'rms' and `critic.heads` 'scalar'."""
  for section, fields in V8_FIELDS.items():
    if section in saved:
      fill(saved, section, fields)


# Field added in version 9, with the value that changes nothing: the proposal's loss weights every
# sequence alike.
V9_FIELDS = {'loss': dict(act_weighting='uniform')}


def to_v9(saved: dict) -> None:
  """Version 8 -> 9 (in place): `loss.act_weighting` 'uniform'."""
  for section, fields in V9_FIELDS.items():
    if section in saved:
      fill(saved, section, fields)


# Field added in version 10, with the value that changes nothing: the proposal denoises the
# executed actions.
V10_FIELDS = {'loss': dict(act_target='executed')}


def to_v10(saved: dict) -> None:
  """Version 9 -> 10 (in place): `loss.act_target` 'executed'."""
  for section, fields in V10_FIELDS.items():
    if section in saved:
      fill(saved, section, fields)


# Field added in version 11, with the value that changes nothing: images without the robot's state.
V11_FIELDS = {'model': dict(proprio=False)}


def to_v11(saved: dict) -> None:
  """Version 10 -> 11 (in place): `model.proprio` False."""
  for section, fields in V11_FIELDS.items():
    if section in saved:
      fill(saved, section, fields)


# version -> the step that brings a config of version - 1 to it.
STEPS = {1: to_v1, 2: to_v2, 3: to_v3, 4: to_v4, 5: to_v5, 6: to_v6, 7: to_v7, 8: to_v8,
         9: to_v9, 10: to_v10, 11: to_v11}


def migrate(saved: dict) -> dict:
  """A copy of `saved` (a loaded config.json: nested plain dicts, left as it is) brought to
  CONFIG_VERSION; one-line ValueError for a config saved by a newer version of this code."""
  if not isinstance(saved, dict):
    raise TypeError(f'migrate takes a saved config as a dict, not a {type(saved).__name__}')
  version = int(saved['version']) if 'version' in saved else 0
  if version > CONFIG_VERSION:
    raise ValueError(f'this config has version {version}, newer than this code reads '
                     f'({CONFIG_VERSION}): update ld_mpc_jax to load it')
  out = copy.deepcopy(saved)
  for step in range(version + 1, CONFIG_VERSION + 1):
    STEPS[step](out)
  out['version'] = CONFIG_VERSION
  return out


def neutral_values() -> dict:
  """{'plan': ..., 'data': ...}: the planner and data fields' values that change nothing against
  a run saved before the field (evaluation cache keys leave them out)."""
  return {'plan': dict(FIELDS['plan'], **V2_FIELDS['plan']), 'data': dict(FIELDS['data'])}


def rename_sections(saved: dict) -> dict:
  """Moves each old section of RENAMED_SECTIONS to its new name, where the new one is absent
  (in place), and returns `saved`."""
  for old, new in RENAMED_SECTIONS.items():
    if old in saved and new not in saved:
      saved[new] = saved.pop(old)
  return saved


def renamed_hint(dotted: str) -> str:
  """' (config.objective is now config.critic)' when the dotted field name (with or without a
  leading 'config.') starts with a renamed section, else ''."""
  parts = dotted.split('.')
  section = parts[1] if parts[0] == 'config' and len(parts) > 1 else parts[0]
  new = RENAMED_SECTIONS.get(section)
  return f' (config.{section} is now config.{new})' if new else ''


def fill(saved: dict, section: str, fields: dict) -> None:
  """Adds to saved[section] the `fields` it lacks (in place)."""
  for name, value in fields.items():
    saved[section].setdefault(name, value)


def fill_model_fields(saved: dict) -> dict:
  """Adds the fields above that `saved` (its sections renamed) lacks (in place), returns it."""
  if 'critic' not in saved:
    saved['critic'] = dict(LEGACY_CRITIC)
  for section, fields in MODEL_FIELDS.items():
    fill(saved, section, fields)
  return saved
