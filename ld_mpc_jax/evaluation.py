"""Meta-World success evaluation of any policy, noise sweeps and videos.

Protocol (as `metaworld.evaluation.evaluation` does it): the environment
terminates an episode at the first `info['success']` (here checked at every
repeated sub-step), episodes last at most `max_episode_steps` = 500
ENVIRONMENT steps, and an episode counts as a success iff success was reached.
Episodes are seeded: episode i resets with `episode_seeds(seed, n, 'eval')[i]`,
which picks one of the task's 50 MT1 goal configurations (fixed by `seed`) and
seeds the observation noise; different seeds give unrelated episodes, and the
collection stream never shares episode seeds with evaluation.
"""

import math
import os
import time
import warnings
from typing import Any, Callable, Dict, List, Optional, Sequence

import numpy as np
import tqdm

from ld_mpc_jax.envs import metaworld_env

Policy = Callable[[np.ndarray], np.ndarray]


def wilson_interval(successes: int, n: int, z: float = 1.96) -> List[float]:
  """Wilson score interval [lo, hi] for a binomial proportion (95% at z=1.96)."""
  if n <= 0:
    return [0.0, 1.0]
  p = successes / n
  denom = 1.0 + z * z / n
  center = (p + z * z / (2 * n)) / denom
  half = z / denom * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
  return [max(0.0, center - half), min(1.0, center + half)]


def _write_video(frames: List[np.ndarray], path: str, fps: int) -> str:
  """Writes uint8 frames [H, W, 3] to mp4 (needs imageio-ffmpeg) or gif."""
  import imageio.v2 as imageio  # pylint: disable=g-import-not-at-top
  os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
  if path.endswith('.mp4'):
    try:
      imageio.mimsave(path, frames, fps=fps)
      return path
    except Exception as err:  # pylint: disable=broad-except
      gif = path[:-4] + '.gif'
      warnings.warn(f'Cannot write mp4 ({err}); install imageio-ffmpeg for '
                    f'mp4. Writing {gif} instead.')
      path = gif
  imageio.mimsave(path, frames, duration=1000.0 / fps, loop=0)
  return path


def evaluate(policy: Policy, task: str, num_episodes: int = 50, seed: int = 0,
             action_repeat: int = 2,
             max_episode_steps: int = metaworld_env.METAWORLD_MAX_PATH_LENGTH,
             obs_noise_std: float = 0.0, video_path: Optional[str] = None,
             reset: Optional[Callable[[], Any]] = None,
             env_factory: Optional[Callable[..., Any]] = None,
             video_episodes: int = 3, image_size: int = 256,
             progress: bool = True) -> Dict[str, Any]:
  """Runs `num_episodes` seeded episodes of `policy` under the protocol.

  Args:
    policy: obs [obs_dim] float64 -> action [act_dim] in [-1, 1].
    task: Meta-World v3 task name.
    num_episodes: episodes (Meta-World uses 50 per task).
    seed: MT1 seed of the environment and base of the episode seeds.
    action_repeat: environment steps per decision.
    max_episode_steps: limit in environment steps (500 in the protocol).
    obs_noise_std: Gaussian observation noise (robustness sweeps).
    video_path: if set, the first `video_episodes` episodes are rendered to
      this .mp4/.gif (MuJoCo offscreen rendering: MUJOCO_GL=osmesa).
    reset: called before each episode (e.g. to clear a planner's warm start).
    env_factory: replaces `make_env`; called with the keyword arguments of
      `make_env` (task, seed, action_repeat, max_episode_steps, obs_noise_std,
      terminate_on_success=True, and render_mode/image_size when rendering).
    video_episodes: how many episodes go into the video.
    image_size: rendered frame size.
    progress: show a tqdm progress bar.

  Returns:
    dict(success_rate, success_ci95=[lo, hi] (Wilson), mean_return,
    mean_length (decisions per episode), mean_env_steps, decisions_per_s
    (policy calls per second of time spent in the policy), num_episodes,
    successes (per-episode list of 0/1), video_path).
  """
  if num_episodes < 1:
    raise ValueError(f'num_episodes must be >= 1, got {num_episodes}')
  factory = env_factory or metaworld_env.make_env
  kwargs = dict(task=task, seed=seed, action_repeat=action_repeat,
                max_episode_steps=max_episode_steps,
                obs_noise_std=obs_noise_std, terminate_on_success=True)
  env = factory(**kwargs)
  video_env = None
  if video_path:
    video_env = factory(**kwargs, render_mode='rgb_array',
                        image_size=image_size)
  # The protocol bounds episodes by environment steps; this also bounds
  # environments that do not truncate by themselves.
  max_decisions = -(-max_episode_steps // action_repeat)
  seeds = metaworld_env.episode_seeds(seed, num_episodes, 'eval')
  successes, returns, lengths, env_steps = [], [], [], []
  frames: List[np.ndarray] = []
  policy_time, calls = 0.0, 0
  bar = tqdm.tqdm(range(num_episodes), desc=f'evaluate {task}',
                  disable=not progress)
  for i in bar:
    e = video_env if (video_env is not None and i < video_episodes) else env
    if reset is not None:
      reset()
    obs, _ = e.reset(seed=int(seeds[i]))
    success, ep_return, t, info = False, 0.0, 0, {}
    while t < max_decisions:
      if e is video_env:
        frames.append(np.asarray(e.render(), np.uint8))
      start = time.perf_counter()
      action = policy(obs)
      policy_time += time.perf_counter() - start
      calls += 1
      obs, reward, terminated, truncated, info = e.step(action)
      ep_return += float(reward)
      t += 1
      success = success or bool(info.get('success', False))
      if success or terminated or truncated:
        break
    successes.append(int(success))
    returns.append(ep_return)
    lengths.append(t)
    env_steps.append(int(info.get('env_steps', t * action_repeat)))
    bar.set_postfix(success=float(np.mean(successes)))
  for e in (env, video_env):
    if e is not None and hasattr(e, 'close'):
      e.close()
  written = _write_video(frames, video_path, fps=20) if video_path else None
  k = int(np.sum(successes))
  return dict(
      success_rate=k / num_episodes,
      success_ci95=wilson_interval(k, num_episodes),
      mean_return=float(np.mean(returns)),
      mean_length=float(np.mean(lengths)),
      mean_env_steps=float(np.mean(env_steps)),
      decisions_per_s=calls / policy_time if policy_time > 0 else float('inf'),
      num_episodes=num_episodes, successes=successes, video_path=written)


def noise_sweep(policy: Policy, task: str, stds: Sequence[float],
                **kwargs) -> List[Dict[str, Any]]:
  """`evaluate` at each observation-noise std; results carry 'obs_noise_std'."""
  results = []
  for std in stds:
    result = evaluate(policy, task, obs_noise_std=float(std), **kwargs)
    result['obs_noise_std'] = float(std)
    results.append(result)
  return results


def scripted_policy_with_noise(task: str, noise_std: float,
                               random_prob: float = 0.0,
                               seed: int = 0) -> Policy:
  """Meta-World's scripted policy with the collection's action noise.

  Used to measure the scripted policy's success under the protocol at a
  dataset preset's noise level.
  """
  base = metaworld_env.scripted_policy(task)
  rng = np.random.default_rng(seed)

  def policy(obs: np.ndarray) -> np.ndarray:
    with warnings.catch_warnings():
      warnings.simplefilter('ignore', UserWarning)
      action = base(obs).astype(np.float64)
    action = action + noise_std * rng.standard_normal(action.shape)
    if rng.random() < random_prob:
      action = rng.uniform(-1.0, 1.0, action.shape)
    return np.clip(action, -1.0, 1.0).astype(np.float32)

  return policy
