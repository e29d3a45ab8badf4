"""Config overrides by dotted name, shared by the launchers (no flags defined here)."""

from typing import Any, Dict

import ml_collections


def with_overrides(config: ml_collections.ConfigDict,
                   overrides: Dict[str, Any]) -> ml_collections.ConfigDict:
  """A copy of config with dotted fields set, e.g. {'model.dynamics_type': 'mlp'}.

  String values are converted to the field's type ('4' -> 4 for an int field), so command-line
  overrides work too. Unknown fields raise ValueError naming the field.
  """
  c = ml_collections.ConfigDict(config.to_dict())
  for dotted, value in overrides.items():
    *path, leaf = dotted.split('.')
    node = c
    for part in path:
      if part not in node:
        raise ValueError(f'unknown config field {dotted!r}')
      node = node[part]
    if leaf not in node:
      raise ValueError(f'unknown config field {dotted!r}')
    if isinstance(value, str) and not isinstance(node[leaf], str) and node[leaf] is not None:
      value = type(node[leaf])(value)
    node[leaf] = value
  return c
