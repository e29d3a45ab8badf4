"""ld_mpc_jax.runs.checks.validate_config: bad values fail with one line naming the field; the
online batch against the windows of the seed data; acting settings; the multi-task batch."""

import dataclasses

import numpy as np
import pytest

from ld_mpc_jax.configs import door_open, door_open_online, mt10
from ld_mpc_jax.learn.train_state import OptimSettings
from ld_mpc_jax.model import config_checks
from ld_mpc_jax.model.settings import LossSettings, ModelSettings, PlanSettings
from ld_mpc_jax.online.settings import OnlineSettings
from ld_mpc_jax.runs.checks import check_seeds, validate_config
from ld_mpc_jax import data


def _seed_windows(config) -> int:
  """Windows of the real sampler over the seed waves' episodes (random data of their lengths)."""
  o = config.online
  waves = -(-o.seed_steps // (o.num_envs * o.episode_steps))
  decisions = -(-o.episode_steps // config.eval.action_repeat)
  rng = np.random.default_rng(0)
  episodes = [dict(obs=rng.normal(size=(decisions + 1, config.obs_dim)).astype(np.float32),
                   action=rng.uniform(-1, 1, (decisions, config.action_dim)).astype(np.float32),
                   reward=np.zeros(decisions, np.float32), success=np.zeros(decisions, bool))
              for _ in range(waves * o.num_envs)]
  return data.ReplayBuffer(data.Dataset.from_episodes(episodes), config.horizon + 2).num_windows


@pytest.mark.parametrize('seed_steps', [40, 41, 80])  # 1, 2 and 2 seed waves of 40 steps.
def test_online_batch_may_be_at_most_the_seed_windows(seed_steps):
  config = door_open_online.get_config('smoke')
  config.online.seed_steps = seed_steps
  windows = _seed_windows(config)
  assert windows == 12 * -(-seed_steps // 40)
  config.train.batch_size = windows
  validate_config(config)
  config.train.batch_size = windows + 1
  with pytest.raises(ValueError, match=f'batch_size \\({windows + 1}\\).*{windows} windows'):
    validate_config(config)


def test_online_batch_is_not_checked_without_seed_updates():
  config = door_open_online.get_config('smoke')
  config.train.batch_size = 1000
  with pytest.raises(ValueError, match='batch_size'):
    OnlineSettings.from_config(config).check_budget()
  config.online.env_steps = config.online.seed_steps  # The run ends before its first update.
  OnlineSettings.from_config(config).check_budget()
  config.online.env_steps, config.online.update_ratio = 120, 0.0  # No update at all.
  OnlineSettings.from_config(config).check_budget()
  config.online.update_ratio, config.online.init_from = 0.1, '/runs/offline'  # Its dataset:
  OnlineSettings.from_config(config).check_budget()  # checked at start (runs.check_data_fits).


@pytest.mark.parametrize('overrides, match', [
    (dict(reward='shaped'), "'dense' or 'sparse'"),
    (dict(updates_per_call=0), 'updates_per_call must be an integer'),
    (dict(exec_noise_start=-0.1), 'must be >= 0'),
    (dict(exec_noise_corr=1.0), r'exec_noise_corr must be in \[0, 1\)'),
    (dict(train_goals='fixed'), "train_goals must be one of 'mt1', 'random', got 'fixed'"),
    (dict(train_goals='random'), 'leaves no train goal split'),
])
def test_acting_settings_are_checked(overrides, match):
  c = door_open_online.get_config('smoke')
  c.eval.splits = ('held_out', 'train')
  c.online.update(overrides)
  with pytest.raises(ValueError, match=match):
    validate_config(c)


def test_the_acting_search_is_checked_with_a_message_naming_it():
  c = door_open_online.get_config('cpu')
  c.online.act_iterations = -1
  with pytest.raises(ValueError, match='online.act_iterations must be an integer >= 0'):
    validate_config(c)
  c.online.act_iterations, c.online.act_num_gaussian = 3, 0
  c.plan.num_gaussian = 32
  c.plan.num_elites = 40  # Above the acting first round (24 + 8), not the evaluation's (+ 32).
  with pytest.raises(ValueError, match='while acting .*num_elites'):
    validate_config(c)
  c.online.act_num_gaussian = 32
  validate_config(c)


def test_safe_selection_while_acting_needs_the_actor_priors_sequence():
  c = door_open_online.get_config('smoke')
  c.online.act_safe_selection, c.plan.num_prior_candidates = True, 0
  with pytest.raises(ValueError, match='act_safe_selection needs'):
    validate_config(c)
  c.plan.num_prior_candidates = 1
  validate_config(c)


def test_batch_size_must_split_over_the_tasks():
  c = mt10.get_config('smoke')
  c.train.batch_size = 12
  with pytest.raises(ValueError, match='multiple of the number of tasks'):
    validate_config(c)


def test_log_std_map_is_checked():
  c = door_open_online.get_config('smoke')
  c.critic.log_std_map = 'tanh'
  validate_config(c)
  c.critic.log_std_map = 'softplus'
  with pytest.raises(ValueError, match=r"^config.critic.log_std_map must be one of \('clip', "
                                       r"'tanh'\), got 'softplus'$"):
    validate_config(c)


@pytest.mark.parametrize('field,value,words', [
    ('key_seed', -2, 'config.eval.key_seed must be an integer >= -1'),
    ('action_noise', -0.1, 'config.eval.action_noise must be a std >= 0'),
    ('action_noise', float('nan'), 'config.eval.action_noise must be a std >= 0'),
])
def test_bad_evaluation_draws_fail_naming_the_field(field, value, words):
  config = door_open_online.get_config('smoke')
  config.eval[field] = value
  with pytest.raises(ValueError, match=words):
    validate_config(config)


@pytest.mark.parametrize('field', ['log_every', 'checkpoint_every', 'eval_every',
                                   'max_checkpoints'])
@pytest.mark.parametrize('value', [0, -5])
def test_intervals_and_kept_checkpoints_must_be_positive(field, value):
  config = door_open.get_config('smoke')
  config.train[field] = value
  with pytest.raises(ValueError, match=rf'^config.train.{field} must be an integer >= 1, '
                                       rf'got {value}$'):
    validate_config(config)


@pytest.mark.parametrize('field', ['train.learning_rate', 'plan.temperature', 'loss.w_dyn'])
def test_a_nan_setting_is_refused_naming_it(field):
  """Issue 102: --config.train.learning_rate=nan passed every `<= 0` check and failed 58 s
  later with 'step None'."""
  config = door_open_online.get_config('smoke')
  section, name = field.split('.')
  config[section][name] = float('nan')
  with pytest.raises(ValueError, match=f'config.{field} is NaN'):
    validate_config(config)


def test_the_settings_check_themselves_without_a_config():
  """Issue 103: each check takes the settings it reads, built once from the config."""
  config = door_open.get_config('smoke')
  model, plan = ModelSettings.from_config(config), PlanSettings.from_config(config)
  losses, optim = LossSettings.from_config(config), OptimSettings.from_config(config)
  with pytest.raises(ValueError, match=r'^config.model.width \(30\) must be even'):
    dataclasses.replace(model, width=30, num_heads=4).check_sizes()
  with pytest.raises(ValueError, match=r'^config.gamma must be in \(0, 1\], got 1.5$'):
    dataclasses.replace(model, gamma=1.5).check_targets()
  with pytest.raises(ValueError, match='^config.loss.w_progress must be >= 0'):
    dataclasses.replace(losses, w_progress=-1.0).check_weights()
  with pytest.raises(ValueError, match='^config.plan.warm_start_steps must be 0'):
    config_checks.check_kinds(dataclasses.replace(model, proposal_type='diffusion_step'),
                              dataclasses.replace(plan, warm_start_steps=1))
  with pytest.raises(ValueError, match=r'^config.critic.expectile must be in \(0, 1\)'):
    config_checks.check_critic(model, dataclasses.replace(losses, expectile=1.0), plan)
  with pytest.raises(ValueError, match=r'^config.train.batch_size \(9\) must be a multiple'):
    config_checks.check_tasks(dataclasses.replace(model, num_tasks=2), 9, config.data.source)
  with pytest.raises(ValueError, match='^config.train.seed_devices must be an integer >= 0'):
    check_seeds(2, -1, False)
  optim.check(losses)


def test_the_update_checks_keep_their_order():
  """The EMA's decay, then the batch's weighting and noise, then the optimiser's rates; all
  before the NaN check, so that a NaN decay is named by its range."""
  losses = LossSettings.from_config(door_open.get_config('smoke'))
  bad_losses = dataclasses.replace(losses, reward_balance=2.0, obs_noise_aug=-1.0)
  bad = OptimSettings(learning_rate=0.0, warmup_steps=0, grad_clip=1.0, ema_decay=1.0)
  with pytest.raises(ValueError, match='ema_decay'):
    bad.check(bad_losses)
  with pytest.raises(ValueError, match='reward_balance'):
    dataclasses.replace(bad, ema_decay=0.5).check(bad_losses)
  with pytest.raises(ValueError, match='learning_rate and grad_clip'):
    dataclasses.replace(bad, ema_decay=0.5).check(losses)
  config = door_open.get_config('smoke')
  config.train.ema_decay = float('nan')
  with pytest.raises(ValueError, match=r'^config.train.ema_decay must be in \[0, 1\), got nan$'):
    validate_config(config)


def test_the_builders_check_their_own_settings_and_a_hand_edit_is_blamed(tmp_path):
  """LearnSettings.from_config refuses bad optimiser settings (check_config leaves them to it); the
  commands' loader refuses a config.json whose search settings a hand edit broke, naming the
  file, before any checkpoint is read (checkpointing's own default checks less)."""
  from ld_mpc_jax import LearnSettings  # pylint: disable=g-import-not-at-top
  from ld_mpc_jax.configs.overrides import with_overrides  # pylint: disable=g-import-not-at-top
  from ld_mpc_jax.learn import checkpointing  # pylint: disable=g-import-not-at-top
  from ld_mpc_jax.runs import checks  # pylint: disable=g-import-not-at-top
  config = door_open.get_config('smoke')
  with pytest.raises(ValueError, match='ema_decay'):
    LearnSettings.from_config(with_overrides(config, {'train.ema_decay': 1.5}))
  checkpointing.save_config(with_overrides(config, {'plan.selection': 'bogus'}), str(tmp_path))
  with pytest.raises(checkpointing.WorkdirError,
                     match='config.json is not a valid config.*selection'):
    checks.load_for_evaluation(str(tmp_path))
  with pytest.raises(FileNotFoundError, match='no checkpoint'):  # check_config alone passes it.
    checkpointing.load_for_evaluation(str(tmp_path))


@pytest.mark.parametrize('field,value,words', [
    ('eval.splits', ('held_out', 'valid'), r'^config.eval.splits must name held_out and/or train'),
    ('eval.episodes', -1, r'^config.eval.episodes must be >= 0'),
    ('eval.obs_noise_dims', 'some', r"^config.eval.obs_noise_dims must be 'all' or 'informative'"),
    ('data.source', 'tdmpc2', r'^config.data.source=tdmpc2 needs config.data.path'),
])
def test_eval_and_data_sections_are_checked_beside_their_settings(field, value, words):
  """EvalRounds.check, EvalSettings.check and DataSpec.check, through the run's validate_config;
  check_config (what the model's builders run) leaves these sections to them."""
  config = door_open.get_config('smoke')
  section, name = field.split('.')
  config[section][name] = value
  config_checks.check_config(config)
  with pytest.raises(ValueError, match=words):
    validate_config(config)
