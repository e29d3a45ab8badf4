"""ld_mpc_jax.ops.registry: lookups, one-line errors naming the registered kinds, no duplicates."""

import pytest

from ld_mpc_jax.ops.registry import Registry


def test_register_get_and_order():
  r = Registry('dynamics', 'config.model.dynamics_type')
  r.register('b', 2)

  @r.register('a')
  def a():
    return 1

  assert r.get('a') is a and r.get('b') == 2
  assert r.names() == ('b', 'a') and r.index('a') == 1 and 'a' in r and len(r) == 2


def test_unknown_name_is_one_line_listing_the_kinds():
  r = Registry('dynamics', 'config.model.dynamics_type')
  r.register('mlp', object())
  with pytest.raises(ValueError) as e:
    r.get('nosuch')
  assert str(e.value) == "config.model.dynamics_type must be one of 'mlp', got 'nosuch'"


def test_duplicate_and_unregister():
  r = Registry('actor')
  r.register('bc', 1)
  with pytest.raises(ValueError, match='already registered'):
    r.register('bc', 2)
  r.unregister('bc')
  assert 'bc' not in r
