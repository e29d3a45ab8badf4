"""Config sections renamed and model-side fields added since early runs, with the values that
mean what those runs did.

Library code reads config fields directly (defaults live in experiments/configs/base.py); a
saved config is brought up to date once, on load, by checkpointing.migrate_config, which calls
`rename_sections` and `fill_model_fields` for the names and fields below. This module is the one
place old names are understood; elsewhere they are errors naming the new one (`renamed_hint`).
"""

import ml_collections

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


def rename_sections(config: ml_collections.ConfigDict) -> ml_collections.ConfigDict:
  """Moves each old section of RENAMED_SECTIONS to its new name, where the new one is absent
  (in place), and returns config."""
  for old, new in RENAMED_SECTIONS.items():
    if old in config and new not in config:
      config[new] = config[old]
      del config[old]
  return config


def renamed_hint(dotted: str) -> str:
  """' (config.objective is now config.critic)' when the dotted field name (with or without a
  leading 'config.') starts with a renamed section, else ''."""
  parts = dotted.split('.')
  section = parts[1] if parts[0] == 'config' and len(parts) > 1 else parts[0]
  new = RENAMED_SECTIONS.get(section)
  return f' (config.{section} is now config.{new})' if new else ''


def fill(config: ml_collections.ConfigDict, section: str, fields: dict) -> None:
  """Adds to config[section] the `fields` it lacks (in place)."""
  for name, value in fields.items():
    if name not in config[section]:
      config[section][name] = value


def fill_model_fields(config: ml_collections.ConfigDict) -> ml_collections.ConfigDict:
  """Adds the fields above that `config` (its sections renamed) lacks (in place), returns it."""
  if 'critic' not in config:
    config.critic = ml_collections.ConfigDict(LEGACY_CRITIC)
  for section, fields in MODEL_FIELDS.items():
    fill(config, section, fields)
  return config
