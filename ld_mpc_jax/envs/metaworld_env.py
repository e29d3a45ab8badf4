"""Meta-World v3 environments behind one gymnasium factory.

`make_env(task, seed)` builds Meta-World's own MT1 environment for one task (what
`gym.make('Meta-World/MT1', env_name=task, seed=seed)` builds, with the 50 goal configurations
fixed by `seed` built once per process), and wraps it in `MetaWorldWrapper`, which adds

* action repeat: one decision = `action_repeat` environment steps, rewards summed;
* an episode limit counted in ENVIRONMENT steps (`max_episode_steps`);
* optional termination on success (Meta-World's evaluation protocol);
* seeded Gaussian observation noise;
* seeded episodes: `reset(seed=s)` reseeds the goal choice and the noise, so the
  same `s` always gives the same episode start;
* explicit goals: `reset(seed=s, options={'goal': task})` starts the episode at one given
  goal configuration (a `metaworld.Task`, see `ld_mpc_jax.envs.goals`) instead of drawing one of
  the environment's own 50; `info['goal_vector']` is the start's object and goal position.

Observations are float64 [39] and actions float32 [4] in [-1, 1], as in
Meta-World.
"""

import functools
from typing import Any, Dict, List, Optional, Tuple, Union

import gymnasium as gym
import numpy as np

# Meta-World's observation and action sizes (state observations, v3).
OBS_DIM = 39
ACT_DIM = 4
# Meta-World's own per-episode limit (SawyerXYZEnv.max_path_length).
METAWORLD_MAX_PATH_LENGTH = 500
# Where a state observation holds the (first) object's position and the goal position.
OBJECT_SLICE = slice(4, 7)
GOAL_SLICE = slice(36, 39)
GOAL_DIM = 6  # goal_vector's width: object position and goal position.


def goal_vector(obs: np.ndarray) -> np.ndarray:
  """[..., 39] observations -> [..., 6]: object position and goal position.

  At an episode's first (noise-free) observation this identifies the goal configuration: the
  hand always starts at the same place, and Meta-World's random vector sets the object and goal.
  """
  obs = np.asarray(obs, np.float64)
  return np.concatenate([obs[..., OBJECT_SLICE], obs[..., GOAL_SLICE]], axis=-1)


def task_names() -> List[str]:
  """All Meta-World v3 task names, sorted (e.g. 'door-open-v3')."""
  from metaworld.env_dict import ALL_V3_ENVIRONMENTS  # pylint: disable=g-import-not-at-top
  return sorted(ALL_V3_ENVIRONMENTS.keys())


def check_task(task: str) -> str:
  """Returns `task` if it is a Meta-World v3 task name, else raises ValueError."""
  names = task_names()
  if task not in names:
    raise ValueError(
        f'Unknown Meta-World task {task!r}. Valid v3 task names are: '
        + ', '.join(names))
  return task


@functools.lru_cache(maxsize=64)
def mt1_tasks(task: str, seed: int) -> Tuple[Any, ...]:
  """The 50 goal configurations (`metaworld.Task`) of `metaworld.MT1(task, seed=seed)`.

  Built once per process: building them resets a fresh environment 50 times (about a second),
  and they are immutable. Meta-World draws them from a seeded global NumPy state that it restores.
  """
  import metaworld  # pylint: disable=g-import-not-at-top
  return tuple(metaworld.MT1(check_task(task), seed=int(seed)).train_tasks)


class MetaWorldWrapper(gym.Wrapper):
  """Action repeat, episode limit, success termination and observation noise.

  `step(action)` repeats `action` for up to `action_repeat` environment steps.
  It stops repeating early when a sub-step terminates (with
  `terminate_on_success`, reaching success terminates) or the episode limit is
  hit. The returned reward is the sum over the sub-steps taken, and
  `info['success']` is True if success was reached at ANY sub-step of this
  decision. `info['env_steps']` is the number of environment steps so far in
  the episode and `info['substeps']` those taken by this decision.

  Attributes:
    action_repeat: environment steps per decision.
    max_episode_steps: episode limit in environment steps.
    obs_noise_std: std of Gaussian noise added to every returned observation: one for every
      dimension, or one per dimension ([obs_dim]; 0 leaves a dimension exact).
    terminate_on_success: end the episode at the first successful sub-step.
    random_goals: resets without a goal draw a fresh goal configuration from the task's whole
      random-reset space (seeded by the reset's seed), as TD-MPC2 trains
      (`_freeze_rand_vec = False` in its Meta-World wrapper), instead of one of the 50 of its
      MT1 seed.
  """

  def __init__(self, env: gym.Env, seed: int, action_repeat: int = 2,
               max_episode_steps: int = METAWORLD_MAX_PATH_LENGTH,
               obs_noise_std: Union[float, np.ndarray] = 0.0,
               terminate_on_success: bool = False,
               random_goals: bool = False):
    super().__init__(env)
    if action_repeat < 1:
      raise ValueError(f'action_repeat must be >= 1, got {action_repeat}')
    if max_episode_steps < 1:
      raise ValueError(
          f'max_episode_steps must be >= 1, got {max_episode_steps}')
    if np.any(np.asarray(obs_noise_std) < 0):
      raise ValueError(f'obs_noise_std must be >= 0, got {obs_noise_std}')
    self.action_repeat = int(action_repeat)
    self.max_episode_steps = int(max_episode_steps)
    self.obs_noise_std = (float(obs_noise_std) if np.ndim(obs_noise_std) == 0
                          else np.asarray(obs_noise_std, np.float64))
    self.terminate_on_success = bool(terminate_on_success)
    self.random_goals = bool(random_goals)
    self._noise_rng = np.random.default_rng(seed)
    self._env_steps = 0
    self._needs_reset = True
    # Meta-World raises if stepped past its own max_path_length, and wraps
    # itself in a TimeLimit of that length: lift both to our limit.
    self.env.unwrapped.max_path_length = max(
        self.max_episode_steps, METAWORLD_MAX_PATH_LENGTH)
    inner = self.env
    self._task_select = None  # Meta-World's wrapper that draws one of its 50 goals per reset.
    while isinstance(inner, gym.Wrapper):
      if hasattr(inner, 'toggle_sample_tasks_on_reset'):
        self._task_select = inner
      if isinstance(inner, gym.wrappers.TimeLimit):
        inner._max_episode_steps = self.env.unwrapped.max_path_length  # pylint: disable=protected-access
      if hasattr(inner, 'toggle_terminate_on_success'):
        # Success termination is handled here, per sub-step.
        inner.toggle_terminate_on_success(False)
      inner = inner.env

  def _noisy(self, obs: np.ndarray) -> np.ndarray:
    obs = np.asarray(obs, dtype=np.float64)
    if np.any(self.obs_noise_std > 0):
      obs = obs + self.obs_noise_std * self._noise_rng.standard_normal(
          obs.shape)
    return obs

  def reset(self, *, seed: Optional[int] = None,
            options: Optional[Dict[str, Any]] = None
            ) -> Tuple[np.ndarray, Dict[str, Any]]:
    """Starts an episode; a given `seed` fixes the goal choice and the noise.

    `options={'goal': task}` (a `metaworld.Task` of this environment's task) starts at that goal
    configuration; without it the environment draws one of its own 50 goals with its seeded
    random state, or with `random_goals` a fresh configuration. `info['goal_vector']` ([6],
    `goal_vector` of the noise-free first observation) identifies the configuration.
    """
    options = dict(options or {})
    goal = options.pop('goal', None)
    if seed is not None:
      # SawyerXYZEnv.reset ignores its seed; its np_random picks the goal.
      self.env.unwrapped.seed(int(seed))
      self._noise_rng = np.random.default_rng(int(seed))
    if self._task_select is not None:
      self._task_select.toggle_sample_tasks_on_reset(goal is None and not self.random_goals)
    if goal is None and self.random_goals:
      self._unfreeze_goal()
    if goal is not None:
      if self._task_select is None:
        raise ValueError('this environment has no Meta-World goal configurations to set')
      self.env.unwrapped.set_task(goal)
    obs, info = self.env.reset(options=options or None)
    self._env_steps = 0
    self._needs_reset = False
    info = dict(info)
    info['env_steps'] = 0
    info['goal_vector'] = goal_vector(obs)
    return self._noisy(obs), info

  def _unfreeze_goal(self) -> None:
    """The next reset draws its goal configuration from the environment's seeded np_random."""
    inner = self.env.unwrapped
    if not inner._set_task_called:  # pylint: disable=protected-access
      if self._task_select is None:
        raise ValueError('this environment has no Meta-World goal configuration to start from')
      inner.set_task(self._task_select.tasks[0])  # The task's constants; its goal is redrawn.
    inner._freeze_rand_vec = False  # pylint: disable=protected-access
    inner.seeded_rand_vec = True  # Its np_random (seeded by reset), not NumPy's global state.

  def next_substeps(self) -> int:
    """Environment steps the next decision will take unless the episode terminates inside it (by
    success with `terminate_on_success`: then at least 1). Lets an online run dispatch the updates
    those steps call for before stepping (ld_mpc_jax.runs.online)."""
    if self._needs_reset:
      return 0
    if self.terminate_on_success:
      return 1
    return min(self.action_repeat, self.max_episode_steps - self._env_steps)

  def step(self, action: np.ndarray
           ) -> Tuple[np.ndarray, float, bool, bool, Dict[str, Any]]:
    """action: [act_dim] -> (obs [obs_dim], reward, terminated, truncated, info)."""
    if self._needs_reset:
      raise RuntimeError('Call reset() before step() (episode has ended).')
    action = np.clip(np.asarray(action, dtype=np.float32).reshape(-1),
                     -1.0, 1.0)
    total_reward, success = 0.0, False
    terminated = truncated = False
    info: Dict[str, Any] = {}
    substeps = 0
    for _ in range(self.action_repeat):
      obs, reward, term, trunc, info = self.env.step(action)
      substeps += 1
      self._env_steps += 1
      total_reward += float(reward)
      success = success or bool(info.get('success', 0.0) >= 1.0)
      terminated = bool(term) or (self.terminate_on_success and success)
      truncated = bool(trunc) or self._env_steps >= self.max_episode_steps
      if terminated or truncated:
        break
    info = dict(info)
    info['success'] = success
    info['env_steps'] = self._env_steps
    info['substeps'] = substeps
    self._needs_reset = terminated or truncated
    return self._noisy(obs), total_reward, terminated, truncated, info


def make_env(task: str, seed: int, action_repeat: int = 2,
             max_episode_steps: int = METAWORLD_MAX_PATH_LENGTH,
             obs_noise_std: Union[float, np.ndarray] = 0.0,
             terminate_on_success: bool = False,
             random_goals: bool = False,
             render_mode: Optional[str] = None,
             camera_name: str = 'corner',
             image_size: int = 480) -> MetaWorldWrapper:
  """Builds a wrapped Meta-World v3 environment for one task.

  Args:
    task: Meta-World v3 task name, e.g. 'door-open-v3'.
    seed: seeds the task's 50 goal configurations (Meta-World's MT1 seed), the
      goal choice at unseeded resets and the observation noise.
    action_repeat: environment steps per decision (TD-MPC2 uses 2).
    max_episode_steps: episode limit in ENVIRONMENT steps; with action_repeat=2
      and 500 steps an episode has at most 250 decisions.
    obs_noise_std: std of Gaussian noise added to observations (seeded per episode): a float,
      or one per dimension.
    terminate_on_success: end episodes at the first success (evaluation).
    random_goals: resets without a goal draw a fresh goal configuration
      (MetaWorldWrapper), not one of the 50.
    render_mode: None or 'rgb_array' (offscreen MuJoCo rendering; on a machine
      without a display set MUJOCO_GL=osmesa, needs libosmesa6).
    camera_name: MuJoCo camera used when rendering.
    image_size: rendered frames are [image_size, image_size, 3] uint8.

  Returns:
    A gymnasium environment: obs float64 [39], action float32 [4] in [-1, 1].

  Raises:
    ValueError: unknown task name (the message lists the valid names).
  """
  check_task(task)
  import metaworld  # pylint: disable=g-import-not-at-top
  kwargs = {}
  if render_mode is not None:
    kwargs = dict(render_mode=render_mode, camera_name=camera_name,
                  width=image_size, height=image_size)
  build = getattr(metaworld, '_init_each_env', None)
  if build is None:  # A Meta-World without it: its public factory (rebuilds the 50 goals).
    env = gym.make('Meta-World/MT1', env_name=task, seed=int(seed),
                   disable_env_checker=True, **kwargs)
  else:
    # What gym.make('Meta-World/MT1', env_name=task, seed=seed) builds (metaworld.make_mt_envs,
    # then gymnasium's order check), with the goal configurations built once per process.
    from metaworld.env_dict import ALL_V3_ENVIRONMENTS  # pylint: disable=g-import-not-at-top
    env = gym.wrappers.OrderEnforcing(build(
        env_cls=ALL_V3_ENVIRONMENTS[task], tasks=list(mt1_tasks(task, int(seed))),
        seed=int(seed), num_tasks=1, **kwargs))
  return MetaWorldWrapper(env, seed=int(seed), action_repeat=action_repeat,
                          max_episode_steps=max_episode_steps,
                          obs_noise_std=obs_noise_std,
                          terminate_on_success=terminate_on_success,
                          random_goals=random_goals)


# Independent seed streams, so evaluation never replays a collected (or online) episode.
SEED_STREAMS = {'eval': 0, 'collect': 1, 'online': 2, 'demos': 3}


def episode_seeds(seed: int, num_episodes: int, stream: str) -> np.ndarray:
  """int64 [num_episodes]: per-episode reset seeds for `stream` ('eval'/'collect'/'online'/'demos').

  Episode i's seed is drawn from np.random.SeedSequence([seed, stream, i]), so
  different base seeds and streams give unrelated episodes.
  """
  key = SEED_STREAMS[stream]
  return np.array([
      np.random.SeedSequence([int(seed), key, i]).generate_state(1)[0]
      for i in range(num_episodes)], dtype=np.int64)


def scripted_policy(task: str):
  """Meta-World's scripted expert for `task`: obs [39] -> action [4]."""
  check_task(task)
  from metaworld.policies import ENV_POLICY_MAP  # pylint: disable=g-import-not-at-top
  if task not in ENV_POLICY_MAP:
    raise ValueError(f'Meta-World has no scripted policy for {task!r}.')
  policy = ENV_POLICY_MAP[task]()
  # A copy: some scripted policies (door-open, button-press) shift parts of the observation
  # they are given in place, which would corrupt the caller's (and a dataset's) observations.
  return lambda obs: np.asarray(policy.get_action(np.array(obs, copy=True)), dtype=np.float32)
