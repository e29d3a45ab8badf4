"""Config overrides by dotted name, shared by the launchers (no flags defined here).

Values given as strings are parsed as ml_collections' own command-line flags parse them, by the
type of the field they replace: `--config.eval.noise_stds=0.0,0.05` is a tuple of floats,
`--config.plan.guidance_scale=0` a float, `False`/`false`/`0` a false bool.
"""

import re
from typing import Any, Dict, Iterable

from absl import flags
import ml_collections
from ml_collections.config_flags import config_path
from ml_collections.config_flags import tuple_parser

_PARSERS = {bool: flags.BooleanParser(), int: flags.IntegerParser(),
            float: flags.FloatParser(), str: flags.ArgumentParser(),
            tuple: tuple_parser.TupleParser()}


def parse_value(config: ml_collections.ConfigDict, dotted: str, text: str) -> Any:
  """The value of `text` for field `dotted` of config, parsed by the field's type."""
  field_type = config_path.get_type(dotted, config)
  parser = _PARSERS.get(field_type)
  if parser is None:  # None-valued or other fields: a Python literal, else the string.
    import ast  # pylint: disable=g-import-not-at-top
    try:
      return ast.literal_eval(text)
    except (SyntaxError, ValueError):
      return text
  try:
    return parser.parse(text)
  except (ValueError, TypeError) as err:
    raise ValueError(f'config field {dotted!r} ({field_type.__name__}) cannot be {text!r}: '
                     f'{err}') from None


def _unknown(dotted: str) -> ValueError:
  """The error for an override of no such field (naming a renamed section's new name)."""
  from ld_mpc_jax.ops.legacy import renamed_hint  # pylint: disable=g-import-not-at-top
  return ValueError(f'unknown config field {dotted!r}{renamed_hint(dotted)}')


def with_overrides(config: ml_collections.ConfigDict,
                   overrides: Dict[str, Any]) -> ml_collections.ConfigDict:
  """A copy of config with dotted fields set, e.g. {'model.dynamics_type': 'mlp'}.

  String values are parsed by the field's type (module docstring), so command-line overrides
  work too. Unknown fields raise ValueError naming the field.
  """
  c = ml_collections.ConfigDict(config.to_dict())
  for dotted, value in overrides.items():
    *path, leaf = dotted.split('.')
    node = c
    for part in path:
      if part not in node or not isinstance(node[part], ml_collections.ConfigDict):
        raise _unknown(dotted)
      node = node[part]
    if leaf not in node:
      raise _unknown(dotted)
    if isinstance(value, str) and not isinstance(node[leaf], str):
      value = parse_value(c, dotted, value)
    node[leaf] = value
  return c


def parse_items(items: Iterable[str]) -> Dict[str, str]:
  """['a.b=1', ...] -> {'a.b': '1'}; an item without '=' raises ValueError."""
  out = {}
  for item in items:
    name, sep, value = item.partition('=')
    if not sep or not name:
      raise ValueError(f'override {item!r} is not of the form field.name=value')
    out[name] = value
  return out


# A comma starts a new item only where a dotted field name and '=' follow it, so tuple values
# keep theirs: 'plan.first_round=proposal,gaussian,plan.iterations=0' is two items.
_ITEM_START = re.compile(r',\s*(?=[A-Za-z_][\w.]*\s*=)')


def parse_variant(text: str):
  """'safe1:plan.safe_selection=True,plan.safe_margin=1.0' -> ('safe1', {field: value}); a bare
  name is one of the named variants (ld_mpc_jax/configs/variants.py), e.g. 'safe'.

  Tuple values keep their commas: 'k:plan.first_round=proposal,gaussian' sets one field."""
  from ld_mpc_jax.configs.variants import VARIANTS  # pylint: disable=g-import-not-at-top
  name, sep, rest = text.partition(':')
  if not sep and name in VARIANTS:
    return name, dict(VARIANTS[name])
  if not sep or not name:
    raise ValueError(f'--variant must be a named variant {sorted(VARIANTS)} or '
                     f'NAME:field=value,..., got {text!r}')
  return name, parse_items(item.strip() for item in _ITEM_START.split(rest) if item.strip())
