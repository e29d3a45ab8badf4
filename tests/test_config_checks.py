"""ld_mpc_jax.model.config_checks: bad values fail with one line naming the field; the online batch
against the windows of the seed data; acting settings; the multi-task batch."""

import numpy as np
import pytest

from ld_mpc_jax.configs import door_open, door_open_online, mt10
from ld_mpc_jax.model import config_checks
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
  config_checks.validate_config(config)
  config.train.batch_size = windows + 1
  with pytest.raises(ValueError, match=f'batch_size \\({windows + 1}\\).*{windows} windows'):
    config_checks.validate_config(config)


def test_online_batch_is_not_checked_without_seed_updates():
  config = door_open_online.get_config('smoke')
  config.train.batch_size = 1000
  with pytest.raises(ValueError, match='batch_size'):
    config_checks.check_online_budget(config)
  config.online.env_steps = config.online.seed_steps  # The run ends before its first update.
  config_checks.check_online_budget(config)
  config.online.env_steps, config.online.update_ratio = 120, 0.0  # No update at all.
  config_checks.check_online_budget(config)
  config.online.update_ratio, config.online.init_from = 0.1, '/runs/offline'  # Its dataset:
  config_checks.check_online_budget(config)  # checked at start (runs.check_config_for_data).


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
    config_checks.validate_config(c)


def test_the_acting_search_is_checked_with_a_message_naming_it():
  c = door_open_online.get_config('cpu')
  c.online.act_iterations = -1
  with pytest.raises(ValueError, match='online.act_iterations must be an integer >= 0'):
    config_checks.validate_config(c)
  c.online.act_iterations, c.online.act_num_gaussian = 3, 0
  c.plan.num_gaussian = 32
  c.plan.num_elites = 40  # Above the acting first round (24 + 8), not the evaluation's (+ 32).
  with pytest.raises(ValueError, match='while acting .*num_elites'):
    config_checks.validate_config(c)
  c.online.act_num_gaussian = 32
  config_checks.validate_config(c)


def test_safe_selection_while_acting_needs_the_actor_priors_sequence():
  c = door_open_online.get_config('smoke')
  c.online.act_safe_selection, c.plan.num_prior_candidates = True, 0
  with pytest.raises(ValueError, match='act_safe_selection needs'):
    config_checks.validate_config(c)
  c.plan.num_prior_candidates = 1
  config_checks.validate_config(c)


def test_batch_size_must_split_over_the_tasks():
  c = mt10.get_config('smoke')
  c.train.batch_size = 12
  with pytest.raises(ValueError, match='multiple of the number of tasks'):
    config_checks.validate_config(c)


def test_log_std_map_is_checked():
  c = door_open_online.get_config('smoke')
  c.critic.log_std_map = 'tanh'
  config_checks.validate_config(c)
  c.critic.log_std_map = 'softplus'
  with pytest.raises(ValueError, match=r"^config.critic.log_std_map must be one of \('clip', "
                                       r"'tanh'\), got 'softplus'$"):
    config_checks.validate_config(c)


@pytest.mark.parametrize('field,value,words', [
    ('key_seed', -2, 'config.eval.key_seed must be an integer >= -1'),
    ('action_noise', -0.1, 'config.eval.action_noise must be a std >= 0'),
    ('action_noise', float('nan'), 'config.eval.action_noise must be a std >= 0'),
])
def test_bad_evaluation_draws_fail_naming_the_field(field, value, words):
  config = door_open_online.get_config('smoke')
  config.eval[field] = value
  with pytest.raises(ValueError, match=words):
    config_checks.validate_config(config)


@pytest.mark.parametrize('field', ['log_every', 'checkpoint_every', 'eval_every',
                                   'max_checkpoints'])
@pytest.mark.parametrize('value', [0, -5])
def test_intervals_and_kept_checkpoints_must_be_positive(field, value):
  config = door_open.get_config('smoke')
  config.train[field] = value
  with pytest.raises(ValueError, match=rf'^config.train.{field} must be an integer >= 1, '
                                       rf'got {value}$'):
    config_checks.validate_config(config)


@pytest.mark.parametrize('field', ['train.learning_rate', 'plan.temperature', 'loss.w_dyn'])
def test_a_nan_setting_is_refused_naming_it(field):
  """Issue 102: --config.train.learning_rate=nan passed every `<= 0` check and failed 58 s
  later with 'step None'."""
  config = door_open_online.get_config('smoke')
  section, name = field.split('.')
  config[section][name] = float('nan')
  with pytest.raises(ValueError, match=f'config.{field} is NaN'):
    config_checks.validate_config(config)
