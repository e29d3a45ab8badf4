"""Meta-World success evaluation: episodes in lockstep, per-episode records, noise sweeps, video.

Protocol (as Meta-World's own evaluation does it): the environment terminates an episode at
the first `info['success']` (here checked at every repeated sub-step), episodes last at most
`max_episode_steps` = 500 ENVIRONMENT steps, and an episode counts as a success iff success was
reached. Which goal configuration each episode starts from, and its seeds, are given by an
`ld_mpc_jax.envs.goals.Episode` list (held-out or train goals); `evaluate` with a plain seed
uses the environment's own seeded goal draw instead.

`run_episodes` steps N environments in lockstep: each decision makes one call of a batched
policy for all N (`ld_mpc_jax.plan.agent.make_batch_policy`: one jitted call), so N episodes cost one
dispatch per decision. It returns one record per episode: evaluation seed, split, episode index,
goal id, success, `first_success` (the decision, counted from 1, at which success first came;
None without success), return, length (decisions) and environment steps.
"""

import collections
import os
import time
import warnings
from typing import Any, Callable, Dict, List, Optional, Protocol, Sequence, Tuple

import numpy as np
import tqdm

from ld_mpc_jax.ops import stats
from ld_mpc_jax import envs
from ld_mpc_jax.envs import goals as goals_lib

Policy = Callable[[np.ndarray], np.ndarray]
wilson_interval = stats.wilson_interval


class BatchPolicy(Protocol):
  """Acts for N environments at once."""

  def start(self, episodes: Sequence[goals_lib.Episode]) -> None:
    """Starts a wave of len(episodes) episodes (clears warm starts, sets per-episode keys)."""

  def __call__(self, obs: np.ndarray, t: int, active: np.ndarray) -> np.ndarray:
    """obs [N, obs_dim], decision index t, active bool [N] -> actions [N, A]."""


class CallablePolicy:
  """A `policy(obs) -> action` as a BatchPolicy; `reset(episode)` starts each episode."""

  def __init__(self, policy: Policy, reset: Optional[Callable[[Any], None]] = None):
    self.policy, self.reset = policy, reset

  def start(self, episodes):
    if self.reset is not None:
      for episode in episodes:  # A stateful policy is only used one episode at a time.
        self.reset(episode)

  def warmup(self, obs: np.ndarray) -> None:
    if hasattr(self.policy, 'warmup'):  # e.g. ld_mpc_jax.plan.agent.make_policy: compiles it.
      self.policy.warmup(obs[0])

  def __call__(self, obs, t, active):
    out = None
    for i in np.flatnonzero(active):
      a = np.asarray(self.policy(obs[i]))
      if out is None:
        out = np.zeros((obs.shape[0],) + a.shape, a.dtype)
      out[i] = a
    return out


_NO_PREEXEC = 'IMAGEIO_FFMPEG_NO_PREVENT_SIGINT'


def _write_video(frames: List[np.ndarray], path: str, fps: int) -> str:
  """Writes uint8 frames [H, W, 3] to mp4 (needs imageio-ffmpeg) or gif."""
  import imageio.v2 as imageio  # pylint: disable=g-import-not-at-top
  os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
  if path.endswith('.mp4'):
    # imageio-ffmpeg starts ffmpeg with a Python preexec_fn (its own process group), which runs
    # Python in the forked child of this multithreaded (JAX) process: JAX warns that this can
    # deadlock. Its switch below starts ffmpeg without it (a Ctrl-C then reaches ffmpeg too).
    no_preexec = os.environ.get(_NO_PREEXEC)
    os.environ[_NO_PREEXEC] = '1'
    try:
      imageio.mimsave(path, frames, fps=fps)
      return path
    except Exception as err:  # pylint: disable=broad-except
      gif = path[:-4] + '.gif'
      warnings.warn(f'Cannot write mp4 ({err}); install imageio-ffmpeg for '
                    f'mp4. Writing {gif} instead.')
      path = gif
    finally:
      if no_preexec is None:
        del os.environ[_NO_PREEXEC]
      else:
        os.environ[_NO_PREEXEC] = no_preexec
  imageio.mimsave(path, frames, duration=1000.0 / fps, loop=0)
  return path


# Environments kept between calls, per (factory, settings): one Meta-World environment holds
# about 30 MB, so 50 of each of MT10's ten tasks would hold 15 GB. Only the pools of the
# MAX_ENV_POOLS settings used last are kept; older ones are closed.
MAX_ENV_POOLS = 2
_ENV_POOL: 'collections.OrderedDict[Tuple, List[Any]]' = collections.OrderedDict()


def _envs(factory, n: int, kwargs: Dict[str, Any]) -> List[Any]:
  """n environments of factory(**kwargs), kept for the next call (building one takes ~0.5 s);
  the least recently used settings' environments are closed beyond MAX_ENV_POOLS."""
  key = (factory, tuple(sorted(kwargs.items())))
  pool = _ENV_POOL.setdefault(key, [])
  _ENV_POOL.move_to_end(key)
  while len(_ENV_POOL) > MAX_ENV_POOLS:
    _, old = _ENV_POOL.popitem(last=False)
    for env in old:
      if hasattr(env, 'close'):
        env.close()
  while len(pool) < n:
    pool.append(factory(**kwargs))
  return pool[:n]


def seeded_episodes(seed: int, num_episodes: int) -> List[goals_lib.Episode]:
  """Episodes that draw the environment's own goal (no explicit goal), reset-seeded by `seed`."""
  seeds = envs.episode_seeds(seed, num_episodes, 'eval')
  return [goals_lib.Episode(split='env', index=i, eval_seed=int(seed), reset_seed=int(s),
                            goal_id='', goal=None) for i, s in enumerate(seeds)]


def run_episodes(policy: BatchPolicy, episodes: Sequence[goals_lib.Episode], task: str, *,
                 batch_size: int = 1, action_repeat: int = 2,
                 max_episode_steps: int = envs.MAX_EPISODE_STEPS,
                 obs_noise_std: float = 0.0, env_factory: Optional[Callable[..., Any]] = None,
                 video_path: Optional[str] = None, video_episodes: int = 3,
                 image_size: int = 256, env_seed: int = 0, progress: bool = True,
                 desc: str = 'evaluate') -> Tuple[List[dict], Dict[str, Any]]:
  """Runs `episodes` in waves of `batch_size` environments stepped in lockstep.

  Args:
    policy: a BatchPolicy; called once per decision for the whole wave.
    episodes: what to run (`ld_mpc_jax.envs.goals.make_episodes` or `seeded_episodes`).
    task: Meta-World v3 task name.
    batch_size: environments per wave.
    action_repeat, max_episode_steps, obs_noise_std: as in `make_env`.
    env_factory: replaces `make_env` (called with its keyword arguments).
    video_path: if set, the first environment of the first `video_episodes` waves is rendered
      to this .mp4 (imageio-ffmpeg) or .gif (MUJOCO_GL=osmesa on a headless machine).
    env_seed: MT1 seed of the environments (their own goal draw, for `seeded_episodes`).
    progress: show a tqdm bar over the waves' decisions (episodes ended and solved beside it).

  Returns:
    (records, info): one record per episode (module docstring), and info = dict(seconds,
    decisions, decisions_per_s, video_path). `decisions_per_s` counts environment decisions per
    second of the episode loop: policy calls, environment steps and resets included; the
    policy's compilation is not (a warm-up call precedes the loop).
  """
  if not episodes or batch_size < 1:
    raise ValueError(f'no episodes to run ({len(episodes)}) or batch_size < 1 ({batch_size})')
  factory = env_factory or envs.make_env
  kwargs = dict(task=task, seed=int(env_seed), action_repeat=action_repeat,
                max_episode_steps=max_episode_steps, obs_noise_std=obs_noise_std,
                terminate_on_success=True)
  n_env = min(batch_size, len(episodes))
  pool = _envs(factory, n_env, kwargs)
  video_env = (factory(**kwargs, render_mode='rgb_array', image_size=image_size)
               if video_path else None)
  # The protocol bounds episodes by environment steps (also for environments that do not
  # truncate by themselves).
  max_decisions = -(-max_episode_steps // action_repeat)
  records, frames, seconds = [], [], 0.0
  bar = _progress_bar(-(-len(episodes) // n_env), max_decisions, desc, progress)
  for w, first in enumerate(range(0, len(episodes), n_env)):
    wave = list(episodes[first:first + n_env])
    slots = list(pool[:len(wave)])
    if video_env is not None and w < video_episodes:
      slots[0] = video_env
    recs, wave_seconds = _run_wave(policy, wave, slots, max_decisions, action_repeat, bar,
                                   frames if slots[0] is video_env else None, warmup=w == 0)
    seconds += wave_seconds
    records.extend(recs)
    _show_ended(bar, w + 1, max_decisions, records, len(episodes))
  bar.close()
  if video_env is not None and hasattr(video_env, 'close'):
    video_env.close()
  written = _write_video(frames, video_path, fps=20) if video_path else None
  decisions = int(sum(r['length'] for r in records))
  return records, dict(seconds=seconds, decisions=decisions,
                       decisions_per_s=decisions / seconds if seconds > 0 else float('inf'),
                       video_path=written)


def _progress_bar(num_waves: int, max_decisions: int, desc: str, progress: bool):
  """A bar over the waves' decisions. The episodes of a wave step in lockstep and most end
  together at the decision limit, so a bar over episodes read 0 until then; this one's length
  is an upper bound (a wave whose episodes all end early skips the rest)."""
  return tqdm.tqdm(total=num_waves * max_decisions, desc=desc, unit='decision',
                   disable=not progress, dynamic_ncols=True)


def _show_ended(bar, waves_done: int, max_decisions: int, records: Sequence[dict],
                num_episodes: int) -> None:
  """Moves `bar` to the end of wave `waves_done` and shows the episodes ended and solved."""
  if waves_done * max_decisions > bar.n:  # The decisions a wave that ended early skipped.
    bar.update(waves_done * max_decisions - bar.n)
  bar.set_postfix_str(f'episodes {len(records)}/{num_episodes}, '
                      f'solved {sum(r["success"] for r in records)}')


def _run_wave(policy: BatchPolicy, wave: Sequence[goals_lib.Episode], slots: List[Any],
              max_decisions: int, action_repeat: int, bar, frames: Optional[List[np.ndarray]],
              warmup: bool) -> Tuple[List[dict], float]:
  """One wave: len(wave) episodes on `slots` in lockstep; (records, seconds of the loop).

  `frames` (if given) collects slot 0's rendered frames [H, W, 3] while its episode runs.
  """
  obs = np.stack([e.reset(seed=ep.reset_seed,
                          options={'goal': ep.goal} if ep.goal is not None else None)[0]
                  for e, ep in zip(slots, wave)])
  if warmup and hasattr(policy, 'warmup'):
    policy.warmup(obs)  # Compiles outside the timed loop.
  policy.start(wave)
  start_time = time.perf_counter()
  active = np.ones(len(wave), bool)
  rec = [dict(ep.record(), success=0, first_success=None, **{'return': 0.0}, length=0,
              env_steps=0) for ep in wave]
  for t in range(max_decisions):
    if frames is not None and active[0]:
      frames.append(np.asarray(slots[0].render(), np.uint8))
    actions = np.asarray(policy(obs, t, active))
    infos = getattr(policy, 'last_info', None)  # Planners: [N, 7] (agent.NO_PLAN_INFO).
    for i in np.flatnonzero(active):
      if infos is not None:
        _record_info(rec[i], t, infos[i])
      obs[i], reward, terminated, truncated, info = slots[i].step(actions[i])
      _record_step(rec[i], t, reward, info, action_repeat)
      if rec[i]['success'] or terminated or truncated:
        active[i] = False
    bar.update(1)
    if not active.any():
      break
  seconds = time.perf_counter() - start_time
  return rec, seconds


def _record_info(r: dict, t: int, info) -> None:
  """Adds decision t's planner info (agent.NO_PLAN_INFO's fields) to record `r`: `departures`
  counts decisions that left the actor prior's sequence (planners only); with the fallback,
  `fallback_at` is the first decision the actor prior made for it (None while it has not)."""
  if info[0] >= 0:  # A planner: did it leave the actor prior's sequence?
    r['departures'] = r.get('departures', 0) + int(info[2])
  if len(info) > 3 and info[3] >= 0:  # A planner with the fallback (`plan.fallback_drop`).
    r.setdefault('fallback_at', None)
    if info[3] and r['fallback_at'] is None:
      r['fallback_at'] = t


def _record_step(r: dict, t: int, reward: float, info: Dict[str, Any],
                 action_repeat: int) -> None:
  """Adds decision t's reward, length, environment steps and first success to record `r`."""
  r['return'] += float(reward)
  r['length'] = t + 1
  r['env_steps'] = int(info.get('env_steps', (t + 1) * action_repeat))
  if info.get('success', False) and not r['success']:
    r['success'], r['first_success'] = 1, t + 1


def result(records: Sequence[dict], info: Dict[str, Any]) -> Dict[str, Any]:
  """Summary of one evaluation: `stats.summarize` of its records plus timing and records."""
  out = stats.summarize(records)
  out.update(num_episodes=len(records), decisions_per_s=info['decisions_per_s'],
             seconds=info['seconds'], video_path=info.get('video_path'),
             outcomes=[int(r['success']) for r in records], records=list(records))
  return out


def evaluate(policy: Policy, task: str, num_episodes: int = 50, seed: int = 0,
             action_repeat: int = 2,
             max_episode_steps: int = envs.MAX_EPISODE_STEPS,
             obs_noise_std: float = 0.0, video_path: Optional[str] = None,
             reset: Optional[Callable[[Any], None]] = None,
             env_factory: Optional[Callable[..., Any]] = None,
             video_episodes: int = 3, image_size: int = 256,
             episodes: Optional[Sequence[goals_lib.Episode]] = None,
             progress: bool = True) -> Dict[str, Any]:
  """Runs a `policy(obs) -> action` one episode at a time under the protocol.

  Without `episodes`, episode i resets with `episode_seeds(seed, num_episodes, 'eval')[i]` on
  an environment of MT1 seed `seed`, which draws one of that seed's 50 goals (use
  `ld_mpc_jax.envs.goals` episodes for held-out or train goals). `reset(episode)` is called
  before each episode (e.g. to clear a planner's warm start).

  Returns:
    dict(success_rate, success_ci95 (Wilson), successes (count), episodes, mean_return,
    mean_length (decisions), mean_env_steps, decisions_per_s (environment included, compilation
    excluded), num_episodes, outcomes (per-episode 0/1), records, video_path).
  """
  if num_episodes < 1:
    raise ValueError(f'num_episodes must be >= 1, got {num_episodes}')
  episodes = list(episodes) if episodes is not None else seeded_episodes(seed, num_episodes)
  records, info = run_episodes(
      CallablePolicy(policy, reset), episodes, task, batch_size=1, action_repeat=action_repeat,
      max_episode_steps=max_episode_steps, obs_noise_std=obs_noise_std, env_factory=env_factory,
      video_path=video_path, video_episodes=video_episodes, image_size=image_size,
      env_seed=seed, progress=progress, desc=f'evaluate {task}')
  return result(records, info)


def noise_sweep(policy: Policy, task: str, stds: Sequence[float],
                **kwargs) -> List[Dict[str, Any]]:
  """`evaluate` at each observation-noise std; results carry 'obs_noise_std'."""
  results = []
  for std in stds:
    r = evaluate(policy, task, obs_noise_std=float(std), **kwargs)
    r['obs_noise_std'] = float(std)
    results.append(r)
  return results


def scripted_policy_with_noise(task: str, noise_std: float,
                               random_prob: float = 0.0,
                               seed: int = 0) -> Policy:
  """Meta-World's scripted policy with the collection's action noise.

  Used to measure the scripted policy's success under the protocol at a
  dataset preset's noise level.
  """
  base = envs.scripted_policy(task)
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
