"""Evaluates a trained LD-MPC checkpoint under the Meta-World protocol.

  python -m experiments.evaluate --workdir=runs/door_open_cpu [--modes=plan,actor,proposal]

Loads <workdir>/config.json and the latest checkpoint (EMA parameters), runs the protocol for
each mode, an observation-noise sweep for the planner, and (where MuJoCo can render offscreen,
e.g. MUJOCO_GL=osmesa with libosmesa6) a short video. Writes <workdir>/evaluation.json.
"""

import json
import os

from absl import app, flags, logging

_WORKDIR = flags.DEFINE_string('workdir', None, 'Training run directory.')
_MODES = flags.DEFINE_list('modes', ['plan', 'actor', 'proposal'], 'Policies to evaluate.')
_EPISODES = flags.DEFINE_integer('episodes', None, 'Episodes per policy (default: config).')
_SEED = flags.DEFINE_integer('seed', 0, 'Evaluation seed.')
_NOISE = flags.DEFINE_bool('noise_sweep', True, 'Run the observation-noise sweep (planner).')
_VIDEO = flags.DEFINE_bool('video', True, 'Render a short video of the planner if possible.')
_OVERRIDE = flags.DEFINE_multi_string('set', [], 'Config override, e.g. plan.action_steps=4.')
_OUT = flags.DEFINE_string('out', None, 'JSON output (default: <workdir>/evaluation.json).')
flags.mark_flag_as_required('workdir')


def main(argv):
  del argv
  logging.set_verbosity(logging.WARNING)
  from ld_mpc_jax import checkpointing
  from ld_mpc_jax.train import git_commit, run_evaluation
  from experiments.overrides import with_overrides
  config, params, step = checkpointing.load_for_evaluation(_WORKDIR.value)
  config = with_overrides(config, dict(item.split('=', 1) for item in _OVERRIDE.value))
  episodes = _EPISODES.value or config.eval.episodes
  out = {'step': step, 'episodes': episodes, 'seed': _SEED.value, 'overrides': _OVERRIDE.value,
         'git_commit': git_commit(), 'modes': {}}
  for mode in _MODES.value:
    r = run_evaluation(config, params, mode, episodes, _SEED.value)
    out['modes'][mode] = {k: v for k, v in r.items() if k != 'successes'}
    print(f"{mode}: success {r['success_rate']:.2f} {r['success_ci95']} "
          f"return {r['mean_return']:.1f}, {r['decisions_per_s']:.1f} decisions/s")
  if _NOISE.value:
    out['noise_sweep'] = {}
    for std in config.eval.noise_stds:
      r = run_evaluation(config, params, 'plan', episodes, _SEED.value, obs_noise_std=std)
      out['noise_sweep'][str(std)] = {k: r[k] for k in ('success_rate', 'success_ci95',
                                                        'mean_return')}
      print(f"obs noise {std}: success {r['success_rate']:.2f} {r['success_ci95']}")
  if _VIDEO.value:
    path = os.path.join(_WORKDIR.value, 'planner.mp4')
    try:
      # The written path: .gif where mp4 needs the missing imageio-ffmpeg.
      path = run_evaluation(config, params, 'plan', 2, _SEED.value, video_path=path)['video_path']
      out['video'] = path
      print(f'video: {path}')
    except Exception as err:  # Rendering needs an offscreen GL backend; report, don't fail.
      out['video_error'] = f'{type(err).__name__}: {err}'
      print(f'no video ({out["video_error"]}); try MUJOCO_GL=osmesa with libosmesa6 installed')
  path = _OUT.value or os.path.join(_WORKDIR.value, 'evaluation.json')
  os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
  with open(path, 'w') as f:
    json.dump(out, f, indent=2)
  print(f'wrote {path}')


if __name__ == '__main__':
  app.run(main)
