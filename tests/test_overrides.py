"""Dotted config overrides shared by the launchers, parsed by the field's type."""

import pytest

from ld_mpc_jax.configs import overrides
from ld_mpc_jax.configs.overrides import parse_items, with_overrides


def test_overrides_convert_strings_to_the_field_type_and_copy(smoke_config):
  c = with_overrides(smoke_config, {'plan.action_steps': '7', 'plan.action_eta': '0.5',
                                    'task': 'drawer-open-v3', 'model.dynamics_type': 'mlp'})
  assert c.plan.action_steps == 7 and isinstance(c.plan.action_steps, int)
  assert c.plan.action_eta == 0.5 and c.task == 'drawer-open-v3'
  assert c.model.dynamics_type == 'mlp'
  assert smoke_config.plan.action_steps == 2  # The original is untouched.


def test_tuple_bool_and_int_fields_parse(smoke_config):
  smoke_config.eval.flag = True
  c = with_overrides(smoke_config, parse_items([
      'eval.noise_stds=0.0,0.05', 'eval.splits=train', 'model.actor_hidden=(8, 8)',
      'eval.flag=False', 'eval.batch_size=3', 'plan.guidance_scale=1']))
  assert c.eval.noise_stds == (0.0, 0.05)
  assert c.eval.splits == ('train',)
  assert c.model.actor_hidden == (8, 8)
  assert c.eval.flag is False
  assert c.eval.batch_size == 3 and isinstance(c.eval.batch_size, int)
  assert c.plan.guidance_scale == 1.0 and isinstance(c.plan.guidance_scale, float)
  assert with_overrides(smoke_config, {'eval.flag': 'false'}).eval.flag is False
  assert with_overrides(smoke_config, {'eval.flag': 'true'}).eval.flag is True


@pytest.mark.parametrize('field', ['plan.nope', 'nope.action_steps', 'task.nope'])
def test_unknown_fields_are_named(smoke_config, field):
  with pytest.raises(ValueError, match=field):
    with_overrides(smoke_config, {field: 1})


def test_bad_values_and_items_are_named(smoke_config):
  with pytest.raises(ValueError, match='plan.action_steps'):
    with_overrides(smoke_config, {'plan.action_steps': 'many'})
  with pytest.raises(ValueError, match='field.name=value'):
    parse_items(['plan.action_steps'])


def test_parse_variant():
  name, items = overrides.parse_variant(
      'safe1:plan.safe_selection=True, plan.safe_margin=1.0')
  assert name == 'safe1'
  assert items == {'plan.safe_selection': 'True', 'plan.safe_margin': '1.0'}
  assert overrides.parse_variant('argmax:') == ('argmax', {})
  # A tuple value keeps its commas; the next field starts a new item.
  _, items = overrides.parse_variant(
      'g:plan.first_round=proposal,gaussian, plan.iterations=0,eval.noise_stds=0.0,0.1')
  assert items == {'plan.first_round': 'proposal,gaussian', 'plan.iterations': '0',
                   'eval.noise_stds': '0.0,0.1'}
  for bad in ('noname', ':plan.x=1', 'a:plan.x'):
    with pytest.raises(ValueError):
      overrides.parse_variant(bad)


def test_named_variants_apply_to_a_config():
  from ld_mpc_jax.configs import door_open  # pylint: disable=g-import-not-at-top
  from ld_mpc_jax.configs.variants import VARIANTS  # pylint: disable=g-import-not-at-top
  assert overrides.parse_variant('safe') == ('safe', {'plan.safe_selection': 'True'})
  config = door_open.get_config('smoke')
  for name in VARIANTS:  # Every named variant names real fields with values that parse.
    overrides.with_overrides(config, overrides.parse_variant(name)[1])
  full = overrides.with_overrides(config, overrides.parse_variant('safe_full')[1])
  assert (full.plan.safe_selection, full.plan.confirm_draws, full.plan.safe_margin_scaling) == (
      True, 8, 'expected_max')
  with pytest.raises(ValueError, match='named variant'):
    overrides.parse_variant('nosuch')
