"""What an image observation costs (issue 105): milliseconds to render one frame of a Meta-World
task offscreen (ld_mpc_jax.envs.pixels.FrameRenderer), with MuJoCo's default rendering and with
shadows, reflections, the skybox and multisampling off (`fast`), at several sizes, beside the
simulator's own step (one decision: `action_repeat` steps). Medians over `--frames` frames of
one episode (zero actions), after 5 untimed ones.

  MUJOCO_GL=osmesa python -m benchmarks.render --out=results/benchmarks/render_cpu.json

With `--memory=N`, what N environments hold instead (resident memory, MB, one process): the task's
environments alone, as pixel observations with the task's one shared renderer (FrameRenderer), and
the renderer of each environment that the shared one replaced (a mujoco.Renderer each).
"""

import argparse
import os
import time
from typing import List, Optional

import numpy as np

from benchmarks import write_results


def time_frames(task: str, size: int, fast: bool, frames: int, camera: str) -> dict:
  from ld_mpc_jax.envs import metaworld_env  # pylint: disable=g-import-not-at-top
  from ld_mpc_jax.envs.pixels import FrameRenderer  # pylint: disable=g-import-not-at-top
  env = metaworld_env.make_env(task, seed=0)
  env.reset(seed=1)
  renderer = FrameRenderer(env, size, camera, fast)
  render, step = [], []
  for i in range(frames + 5):
    t0 = time.perf_counter()
    env.step(np.zeros(4, np.float32))
    t1 = time.perf_counter()
    image = renderer.frame()
    t2 = time.perf_counter()
    if i >= 5:
      step.append(t1 - t0)
      render.append(t2 - t1)
  renderer.close()
  env.close()
  return dict(task=task, size=size, fast=fast, camera=camera, frames=frames,
              render_ms=float(np.median(render) * 1e3), step_ms=float(np.median(step) * 1e3),
              mean_pixel=float(image.mean()), gl=os.environ.get('MUJOCO_GL', ''))


def _rss_mb() -> float:
  with open('/proc/self/status') as f:
    return int(f.read().split('VmRSS:')[1].split()[0]) / 1024


def memory(task: str, size: int, n: int) -> dict:
  """Resident MB per environment of `n` random-goal environments of `task`, each way."""
  import mujoco  # pylint: disable=g-import-not-at-top
  from ld_mpc_jax.envs import metaworld_env  # pylint: disable=g-import-not-at-top
  from ld_mpc_jax.envs.pixels import PixelObservations  # pylint: disable=g-import-not-at-top
  make = lambda i: metaworld_env.make_env(task, seed=i, random_goals=True)
  make(0).close()  # Imports and first-use allocations before the first reading.
  start = _rss_mb()
  plain = [make(i) for i in range(n)]
  after_plain = _rss_mb()
  pixel = [PixelObservations(make(i), size, frames=1) for i in range(n)]
  for i, env in enumerate(pixel):
    env.reset(seed=i)
  after_shared = _rss_mb()
  own = [mujoco.Renderer(env.unwrapped.model, size, size) for env in plain]
  for renderer, env in zip(own, plain):
    renderer.update_scene(env.unwrapped.data, camera='corner2')
    renderer.render()
  after_own = _rss_mb()
  for x in own + pixel + plain:
    x.close()
  return dict(task=task, size=size, environments=n, env_mb=(after_plain - start) / n,
              pixel_env_shared_mb=(after_shared - after_plain) / n,
              own_renderer_mb=(after_own - after_shared) / n)


def memory_markdown(r: dict) -> str:
  return '\n'.join([
      f"Resident memory per environment, {r['environments']} random-goal environments of "
      f"{r['task']} in one process, {r['size']} x {r['size']} frames (MB).", '',
      '| environment alone | pixel environment, renderer shared | a renderer of its own |',
      '| ---: | ---: | ---: |',
      f"| {r['env_mb']:.1f} | {r['pixel_env_shared_mb']:.1f} | "
      f"{r['own_renderer_mb']:.1f} |"]) + '\n'


def markdown(rows: List[dict]) -> str:
  lines = [f"Offscreen rendering (MUJOCO_GL={rows[0]['gl'] or 'unset'}), {rows[0]['task']}, camera "
           f"{rows[0]['camera']}; medians over {rows[0]['frames']} frames.", '',
           '| size | rendering | render ms | simulator ms a decision | mean pixel |',
           '| ---: | --- | ---: | ---: | ---: |']
  for r in rows:
    lines.append(f"| {r['size']} | {'fast' if r['fast'] else 'MuJoCo default'} | "
                 f"{r['render_ms']:.1f} | {r['step_ms']:.2f} | {r['mean_pixel']:.1f} |")
  return '\n'.join(lines) + '\n'


def main(argv: Optional[List[str]] = None) -> List[dict]:
  parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
  parser.add_argument('--task', default='door-open-v3')
  parser.add_argument('--sizes', default='64,84', help='Frame sizes, comma-separated.')
  parser.add_argument('--frames', type=int, default=50, help='Timed frames per configuration.')
  parser.add_argument('--camera', default='corner2')
  parser.add_argument('--memory', type=int, default=0,
                      help='Measure the memory of this many environments instead (first size).')
  parser.add_argument('--out', default='runs/benchmark/render.json')
  args = parser.parse_args(argv)
  sizes = [int(s) for s in args.sizes.split(',')]
  if args.frames < 1 or min(sizes) < 1 or args.memory < 0:
    parser.error('--frames and every size must be >= 1, --memory >= 0')
  if args.memory:
    row = memory(args.task, sizes[0], args.memory)
    write_results(args.out, [row], memory_markdown(row))
    print(memory_markdown(row))
    return [row]
  rows = [time_frames(args.task, size, fast, args.frames, args.camera)
          for size in sizes for fast in (False, True)]
  write_results(args.out, rows, markdown(rows))
  print(markdown(rows))
  return rows


if __name__ == '__main__':
  main()
