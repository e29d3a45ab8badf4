"""Model-side fields added since early runs, with the values that mean what those runs did.

Library code reads config fields directly (defaults live in experiments/configs/base.py); a
saved config is brought up to date once, on load, by checkpointing.migrate_config, which calls
`fill_model_fields` for the fields below.
"""

import ml_collections

# The critic settings of a run saved before config.objective existed: the behaviour value of
# the sequence objective, a BC actor, no latent rollouts in the loss.
LEGACY_OBJECTIVE = dict(value='behaviour', actor='bc', latent_rollout=False, num_values=1,
                        num_q=2, hidden=(256, 256), expectile=0.7, value_scale=100.0,
                        awr_temperature=1.0, awr_max_weight=100.0, rollout_steps=1,
                        td_target='one_step', entropy_coef=1e-4)
# section -> {field: value for runs saved before it existed}.
MODEL_FIELDS = {
    'model': dict(proposal_type='diffusion_seq', dynamics_type='diffusion_ar',
                  normalize_obs=False, normalize_dynamics=False, task_dim=96),
    'objective': dict(td_target='one_step', entropy_coef=1e-4),
    'loss': dict(w_consistency=0.0, w_q=0.0, w_v=0.0),
}
TASK_DIM = MODEL_FIELDS['model']['task_dim']  # Before it was a field (TD-MPC2's width).


def fill(config: ml_collections.ConfigDict, section: str, fields: dict) -> None:
  """Adds to config[section] the `fields` it lacks (in place)."""
  for name, value in fields.items():
    if name not in config[section]:
      config[section][name] = value


def fill_model_fields(config: ml_collections.ConfigDict) -> ml_collections.ConfigDict:
  """Adds the fields above that `config` lacks (in place) and returns it."""
  if 'objective' not in config:
    config.objective = ml_collections.ConfigDict(LEGACY_OBJECTIVE)
  for section, fields in MODEL_FIELDS.items():
    fill(config, section, fields)
  return config
