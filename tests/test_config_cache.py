"""config_cache: one built function per config (or settings) value; nothing traced twice for equal
values."""

import dataclasses

import jax.numpy as jnp

from ld_mpc_jax.configs import door_open
from ld_mpc_jax.ops import config_cache, registry
from ld_mpc_jax import make_plan
from ld_mpc_jax.model import models
from ld_mpc_jax.learn.train_state import make_update
from ld_mpc_jax.model.settings import ModelSettings, PlanSettings


def test_equal_configs_share_one_built_function_and_others_do_not():
  built = []

  @config_cache.by_config
  def build(config):
    built.append(config.model.width)
    return lambda: config.model.width

  a, b = door_open.get_config('smoke'), door_open.get_config('smoke')
  assert build(a) is build(b) and built == [16]
  b.model.width = 32
  assert build(b) is not build(a) and built == [16, 32]
  # The function was built from a copy: changing the caller's config afterwards changes nothing.
  a.model.width = 64
  assert build(door_open.get_config('smoke'))() == 16


def test_a_registry_change_rebuilds_and_old_entries_are_dropped():
  built = []

  @config_cache.by_config
  def build(config):
    built.append(1)
    return object()

  c = door_open.get_config('smoke')
  first = build(c)
  family = registry.Registry('toy family')
  family.register('toy', object())
  assert build(c) is not first and len(built) == 2
  family.unregister('toy')
  for width in range(config_cache.MAX_ENTRIES + 1):
    c.model.width = 8 + width
    build(c)
  assert build.cache_size() == config_cache.MAX_ENTRIES


def test_builders_trace_once_per_config_value():
  config = door_open.get_config('smoke')
  assert make_plan(config) is make_plan(door_open.get_config('smoke'))
  assert make_update(config) is make_update(door_open.get_config('smoke'))
  # A score function of the caller's own is never cached.
  score = lambda params, latents, actions: jnp.zeros(latents.shape[0])
  assert make_plan(config, score) is not make_plan(config, score)
  # init_params jits one initialiser per model settings' value.
  model = lambda: ModelSettings.from_config(door_open.get_config('smoke'))
  assert models._jitted_init(model()) is models._jitted_init(model())


def test_settings_builders_share_one_function_per_value_and_follow_the_registries():
  built = []

  @config_cache.by_settings
  def build(model, plan):
    built.append(plan.num_candidates)
    return object()

  c = door_open.get_config('smoke')
  m, p = ModelSettings.from_config(c), PlanSettings.from_config(c)
  first = build(m, p)
  assert build(ModelSettings.from_config(c), PlanSettings.from_config(c)) is first
  assert build(m, dataclasses.replace(p, num_candidates=3)) is not first and built[-1] == 3
  family = registry.Registry('toy family')
  family.register('toy', object())
  assert build(m, p) is not first
  family.unregister('toy')
