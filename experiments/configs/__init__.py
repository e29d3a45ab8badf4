"""Experiment configs (ml_collections), and how the launchers find them."""

import os

CONFIG_DIR = os.path.dirname(os.path.abspath(__file__))


def resolve_config_arg(argv):
  """Rewrites --config=name.py[:preset] to a path under experiments/configs when needed."""
  out = []
  for arg in argv:
    if arg.startswith('--config='):
      path, sep, preset = arg[len('--config='):].partition(':')
      if not os.path.exists(path) and os.path.exists(os.path.join(CONFIG_DIR, path)):
        arg = f'--config={os.path.join(CONFIG_DIR, path)}{sep}{preset}'
    out.append(arg)
  return out
