"""Dotted config overrides shared by the launchers."""

import pytest

from experiments.overrides import with_overrides


def test_overrides_convert_strings_to_the_field_type_and_copy(smoke_config):
  c = with_overrides(smoke_config, {'plan.action_steps': '7', 'plan.action_eta': '0.5',
                                    'task': 'drawer-open-v3', 'model.dynamics_type': 'mlp'})
  assert c.plan.action_steps == 7 and isinstance(c.plan.action_steps, int)
  assert c.plan.action_eta == 0.5 and c.task == 'drawer-open-v3'
  assert c.model.dynamics_type == 'mlp'
  assert smoke_config.plan.action_steps == 2  # The original is untouched.


@pytest.mark.parametrize('field', ['plan.nope', 'nope.action_steps'])
def test_unknown_fields_are_named(smoke_config, field):
  with pytest.raises(ValueError, match=field):
    with_overrides(smoke_config, {field: 1})
