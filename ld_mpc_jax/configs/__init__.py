"""Experiment configs (ml_collections), and how the launchers find them."""

import os

CONFIG_DIR = os.path.dirname(os.path.abspath(__file__))


def online_enabled(config) -> bool:
  """Whether config asks for online training (`config.online.enabled`, ld_mpc_jax.runs.online)."""
  return 'online' in config and bool(config.online.enabled)


def schedule_end(online) -> int:
  """Simulator steps at which every annealed schedule of online training ends (the
  demonstrations' share, executed-action noise, `online.act_schedule='linear'`), of an online
  section (`config.online`, or it as a dict): `schedule_steps`, or `env_steps` where it is 0
  (OnlineSettings.schedule_end likewise)."""
  return int(online['schedule_steps'] or online['env_steps'])


def resolve_config_arg(argv):
  """Rewrites --config=name.py[:preset] to a path under experiments/configs when needed.

  The space-separated forms `--config NAME` and `--config.x VALUE` (as absl accepts them) come
  back joined as `--config=NAME` and `--config.x=VALUE`, so that launchers can read the config
  and its overrides from argv. A `--config.x` followed by another flag is left alone (a boolean).
  """
  out, i = [], 0
  while i < len(argv):
    arg = argv[i]
    takes_value = arg == '--config' or (arg.startswith('--config.') and '=' not in arg)
    if takes_value and i + 1 < len(argv) and not argv[i + 1].startswith('--'):
      arg, i = f'{arg}={argv[i + 1]}', i + 1
    if arg.startswith('--config='):
      path, sep, preset = arg[len('--config='):].partition(':')
      if not os.path.exists(path) and os.path.exists(os.path.join(CONFIG_DIR, path)):
        arg = f'--config={os.path.join(CONFIG_DIR, path)}{sep}{preset}'
    out.append(arg)
    i += 1
  return out
