"""build_cache: one built function per settings value; nothing traced twice for equal values."""

import dataclasses

import jax.numpy as jnp

from ld_mpc_jax.configs import door_open
from ld_mpc_jax.ops import build_cache, registry
from ld_mpc_jax import make_plan
from ld_mpc_jax.model import models
from ld_mpc_jax.learn.train_state import LearnSettings, make_update
from ld_mpc_jax.model.settings import ModelSettings, PlanSettings


def _settings(width=16, num_candidates=None):
  c = door_open.get_config('smoke')
  c.model.width = width
  p = PlanSettings.from_config(c)
  return ModelSettings.from_config(c), (p if num_candidates is None else
                                        dataclasses.replace(p, num_candidates=num_candidates))


def test_equal_settings_share_one_built_function_and_others_do_not():
  built = []

  @build_cache.by_settings
  def build(model, plan):
    built.append((model.width, plan.num_candidates))
    return object()

  first = build(*_settings())
  assert build(*_settings()) is first and len(built) == 1
  assert build(*_settings(width=32)) is not first and built[-1][0] == 32
  assert build(*_settings(num_candidates=3)) is not first and built[-1][1] == 3
  assert build(*_settings()) is first and len(built) == 3


def test_a_registry_change_rebuilds_and_old_entries_are_dropped():
  built = []

  @build_cache.by_settings
  def build(model, plan):
    built.append(1)
    return object()

  first = build(*_settings())
  family = registry.Registry('toy family')
  family.register('toy', object())
  assert build(*_settings()) is not first and len(built) == 2
  family.unregister('toy')
  for width in range(build_cache.MAX_ENTRIES + 1):
    build(*_settings(width=8 + width))
  assert build.cache_size() == build_cache.MAX_ENTRIES


def test_settings_given_lists_still_hash():
  """A variant made with dataclasses.replace and a list (as a config holds it) keys the cache."""
  _, plan = _settings()
  variant = dataclasses.replace(plan, first_round=['proposal', 'gaussian'])
  assert variant.first_round == ('proposal', 'gaussian') and hash(variant) == hash(plan)


def test_builders_trace_once_per_settings_value():
  config = door_open.get_config('smoke')
  assert make_plan(config) is make_plan(door_open.get_config('smoke'))
  learn = lambda c: LearnSettings.from_config(c)
  assert make_update(learn(config)) is make_update(learn(door_open.get_config('smoke')))
  # Fields that change neither the model, its loss nor its optimiser share the update.
  other = door_open.get_config('smoke')
  other.eval.episodes, other.train.num_steps = 3, 7
  assert make_update(learn(other)) is make_update(learn(config))
  # A score function of the caller's own is never cached.
  score = lambda params, latents, actions: jnp.zeros(latents.shape[0])
  assert make_plan(config, score) is not make_plan(config, score)
  # init_params jits one initialiser per model settings' value.
  model = lambda: ModelSettings.from_config(door_open.get_config('smoke'))
  assert models._jitted_init(model()) is models._jitted_init(model())
