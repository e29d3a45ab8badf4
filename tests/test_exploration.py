"""ld_mpc_jax.model.exploration: the acting planner's settings, the annealed std of the executed-action
noise and its correlated (AR(1)) draws."""

import json

import numpy as np
import pytest

from experiments.configs import door_open_online
from ld_mpc_jax.model import exploration


def test_acting_config_is_a_copy_with_the_online_noise_and_pessimism():
  c = door_open_online.get_config('smoke')
  c.online.action_noise_std, c.online.prior_noise_std, c.online.act_pessimism = 0.3, 0.4, -0.5
  c.plan.safe_selection, c.online.act_safe_selection = True, False  # Safe only in evaluation.
  plan = c.plan.to_dict()
  acting = exploration.acting_config(c)
  assert (acting.plan.action_noise_std, acting.plan.prior_noise_std, acting.plan.pessimism,
          acting.plan.safe_selection) == (0.3, 0.4, -0.5, False)
  assert c.plan.to_dict() == plan  # The evaluation's config is left as it was.
  others = lambda p: {k: v for k, v in p.items() if k not in (
      'action_noise_std', 'prior_noise_std', 'pessimism', 'safe_selection', 'safe_confirm',
      'fallback_drop')}  # The gates: inert without safe selection, and zeroed with it off.
  assert others(acting.plan.to_dict()) == others(plan)
  assert acting.online.to_dict() == c.online.to_dict()


def test_acting_searches_with_its_own_settings_and_evaluation_with_the_plans():
  c = door_open_online.get_config('cpu')
  assert (c.online.act_num_gaussian, c.online.act_iterations) == (32, 3)  # As the presets act.
  assert (c.plan.num_gaussian, c.plan.iterations) == (0, 0)  # Evaluation: proposal and prior.
  acting = exploration.acting_config(c)
  assert (acting.plan.num_gaussian, acting.plan.iterations) == (32, 3)
  assert (c.plan.num_gaussian, c.plan.iterations) == (0, 0)


def test_acting_keeps_the_safe_selection_gates_only_when_asked():
  c = door_open_online.get_config('cpu')
  c.plan.safe_selection, c.plan.safe_confirm, c.plan.fallback_drop = True, True, 0.1
  acting = exploration.acting_config(c)  # online.act_safe_selection is off in the presets.
  assert not (acting.plan.safe_selection or acting.plan.safe_confirm)
  assert acting.plan.fallback_drop == 0
  c.online.act_safe_selection = True
  acting = exploration.acting_config(c)
  assert acting.plan.safe_confirm and acting.plan.fallback_drop == 0.1


def test_the_cpu_preset_evaluates_without_the_search_it_acts_with():
  c = door_open_online.get_config('cpu')
  assert (c.critic.log_std_map, c.plan.num_gaussian, c.plan.iterations) == ('tanh', 0, 0)
  acting = exploration.acting_config(c)
  assert (acting.plan.num_gaussian, acting.plan.iterations) == (32, 3)  # Acting still searches.
  assert (acting.plan.pessimism, c.online.exec_noise_corr, c.gamma) == (-1.0, 0.85, 0.95)


def test_removed_presets_say_what_to_use():
  with pytest.raises(ValueError, match="preset 'cpu_tanh' is now ':cpu'"):
    door_open_online.get_config('cpu_tanh')
  with pytest.raises(ValueError, match="'cpu_optimistic' was removed .*e421b33"):
    door_open_online.get_config('cpu_optimistic')


def test_executed_noise_anneals_linearly():
  c = door_open_online.get_config('cpu')
  start, end = c.online.exec_noise_start, c.online.exec_noise_end
  assert exploration.executed_noise(c, 0, 1_600) == pytest.approx(start)  # Before learning starts.
  assert exploration.executed_noise(c, 1_600, 1_600) == pytest.approx(start)
  mid = (1_600 + c.online.env_steps) // 2
  assert exploration.executed_noise(c, mid, 1_600) == pytest.approx((start + end) / 2)
  assert exploration.executed_noise(c, c.online.env_steps, 1_600) == pytest.approx(end)


def test_correlated_noise_has_the_annealed_std_and_its_correlation():
  """AR(1) executed-action noise (`online.exec_noise_corr`): stationary std = executed_noise,
  lag-one autocorrelation = the configured correlation."""
  c = door_open_online.get_config('cpu')
  c.online.exec_noise_start = c.online.exec_noise_end = 0.3
  std = exploration.executed_noise(c, 5_000, 1_600)
  rng, noise, draws = np.random.default_rng(0), np.zeros((4, 4)), []
  for _ in range(5_000):
    noise = exploration.ar1_noise(noise, std, c.online.exec_noise_corr, rng)
    draws.append(noise)
  x = np.stack(draws[100:])  # [T, 4, 4], past the start-up from zero.
  assert np.std(x) == pytest.approx(0.3, rel=0.05)
  lag1 = np.mean(x[1:] * x[:-1]) / np.mean(x * x)
  assert lag1 == pytest.approx(0.85, abs=0.02)
