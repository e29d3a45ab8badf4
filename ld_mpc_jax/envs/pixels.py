"""Image observations of a MuJoCo task (issue 105): one camera rendered offscreen after every
decision, the last `frames` frames stacked on the channels and flattened, as the `conv` encoder
and the `conv_frames` dynamics read them (ld_mpc_jax.model.pixels).

Rendering sets the cost: with MuJoCo's defaults a 64 x 64 frame takes about 73 ms under OSMesa on
this 2-core CPU (84 x 84: 59 ms; the frame's size hardly matters), against about 1 ms for the
simulator's own step; with shadows, reflections, the skybox and multisampling off (`fast`, the
default) it takes about 6 ms (`python -m benchmarks.render`, results/benchmarks/render_cpu.md).
The agent sees what it is trained on, so the cheaper picture is the one used throughout.

With `proprio`, the robot's own state follows the frames, as MoDem gives it (Hansen et al. 2023):
the hand's position and the gripper's opening, now and one simulator step before (PROPRIO_INDEX of
Meta-World's 39-dimensional state), 8 floats after the pixels.
"""

import atexit
import functools
import gc
import hashlib
import sys
import threading
from typing import Any, Dict, Tuple
import warnings

import numpy as np

# Rendering features `fast` turns off (mujoco.mjtRndFlag names).
SLOW_FLAGS = ('mjRND_SHADOW', 'mjRND_REFLECTION', 'mjRND_SKYBOX')
# The robot's own state in Meta-World's observation: hand xyz and gripper opening (0-3), and the
# same one simulator step before (18-21); the objects (4-17, 22-35) and the goal (36-38) are not.
PROPRIO_INDEX = (0, 1, 2, 3, 18, 19, 20, 21)


def check_rendering() -> None:
  """A one-line ValueError when MuJoCo cannot render offscreen in this process (call it before
  long work that renders)."""
  import mujoco  # pylint: disable=g-import-not-at-top
  model = mujoco.MjModel.from_xml_string('<mujoco><worldbody><geom size="0.1"/></worldbody>'
                                         '</mujoco>')
  hook, sys.unraisablehook = sys.unraisablehook, lambda *_: None  # A failed Renderer's __del__.
  failure = None
  try:
    with warnings.catch_warnings():
      warnings.simplefilter('ignore')  # GLFW's own warnings without a display.
      mujoco.Renderer(model, 8, 8).close()
  except Exception as err:  # pylint: disable=broad-except (mujoco.FatalError, ImportError, ...)
    failure = type(err).__name__
  gc.collect()  # The half-made Renderer goes now, its complaint unheard.
  sys.unraisablehook = hook
  if failure:
    raise ValueError(f'image observations need offscreen rendering, which fails here ({failure}): '
                     'on a machine without a display set MUJOCO_GL=osmesa (apt-get install -y '
                     'libosmesa6) or MUJOCO_GL=egl')


# Model arrays that reach a frame through the simulator's state alone (mj_kinematics turns them into
# data.xpos, site_xpos, ...): Meta-World moves the objects and goals of an episode there, so the
# environments of one task differ in nothing else that is drawn (tests/test_pixels.py).
KINEMATIC_FIELDS = frozenset(('body_pos', 'body_quat', 'site_pos', 'site_quat'))
_RENDERERS: Dict[tuple, list] = {}  # key -> [mujoco.Renderer, environments using it]
_RENDERERS_LOCK = threading.Lock()


@atexit.register
def close_renderers() -> None:
  """Closes every shared renderer still open (environments an evaluation pool keeps until the
  process ends): at exit, while mujoco's OpenGL modules stand. Left to the interpreter's teardown,
  each renderer's own `__del__` printed two ignored TypeErrors after a run's last line."""
  with _RENDERERS_LOCK:
    for renderer, _ in _RENDERERS.values():
      renderer.close()
    _RENDERERS.clear()


def render_key(model, size: int) -> tuple:
  """What a renderer draws with: the thread (an OSMesa context is made current in its own), the
  frame's size, and a digest of every model array but KINEMATIC_FIELDS with the offscreen
  settings. Environments of one task share it whatever their goals."""
  digest = hashlib.blake2b(digest_size=16)
  for name in sorted(dir(model)):
    value = None if name.startswith('_') or name in KINEMATIC_FIELDS else getattr(model, name, None)
    if isinstance(value, np.ndarray):
      digest.update(name.encode() + str(value.shape).encode() + np.ascontiguousarray(value).data)
  g = model.vis.global_
  digest.update(repr((model.vis.quality.offsamples, g.offwidth, g.offheight, model.stat.extent,
                      model.vis.map.znear, model.vis.map.zfar)).encode())
  return threading.get_ident(), size, digest.hexdigest()


class FrameRenderer:
  """frame() -> uint8 [size, size, 3] of `camera` in the environment's current state.

  The environments of one task share one `mujoco.Renderer` (per thread and frame size;
  `render_key`): a renderer of its own held 165 MB here, so 50 evaluation environments held 8 GB
  of them (`python -m benchmarks.render --memory=20`; a pixel environment holds 30 MB with it
  shared). The shared one draws each environment's own state, the same pixels as its own
  renderer; the last environment's `close` closes it.
  """

  def __init__(self, env, size: int = 64, camera: str = 'corner2', fast: bool = True):
    import mujoco  # pylint: disable=g-import-not-at-top (the environments' package)
    base = env.unwrapped
    self.data, self.camera, self.fast, self.size = base.data, camera, fast, size
    if fast:  # Multisampling is the model's setting: this environment renders without it.
      base.model.vis.quality.offsamples = 0
    self.key = render_key(base.model, size)
    with _RENDERERS_LOCK:
      if self.key not in _RENDERERS:
        _RENDERERS[self.key] = [mujoco.Renderer(base.model, size, size), 0]
      _RENDERERS[self.key][1] += 1
      self.renderer = _RENDERERS[self.key][0]
    self.flags = [getattr(mujoco.mjtRndFlag, name) for name in SLOW_FLAGS]

  def frame(self) -> np.ndarray:
    self.renderer.update_scene(self.data, camera=self.camera)
    if self.fast:
      for flag in self.flags:
        self.renderer.scene.flags[flag] = False
    return self.renderer.render()

  def close(self) -> None:
    """Closes the shared renderer when no other environment uses it; twice is once."""
    if self.renderer is None:
      return
    with _RENDERERS_LOCK:
      entry = _RENDERERS.get(self.key)  # None: closed at exit (close_renderers).
      if entry is not None:
        entry[1] -= 1
        if not entry[1]:
          del _RENDERERS[self.key]
          entry[0].close()
    self.renderer = None


class PixelObservations:
  """Wraps an environment (reset, step) so that its observation is the last `frames` frames,
  oldest first, stacked on the channels and flattened: float32 [size * size * 3 frames] in
  [0, 255], then with `proprio` the robot's state (PROPRIO_INDEX of the state observation).
  info['state'] keeps the state observation (for scripted policies and diagnostics). At reset
  the first frame fills the stack."""

  def __init__(self, env, size: int = 64, frames: int = 3, camera: str = 'corner2',
               fast: bool = True, proprio: bool = False):
    if frames < 1 or size < 1:
      raise ValueError(f'image observations need frames >= 1 and size >= 1, got {frames}, {size}')
    self.env, self.frames, self.proprio = env, frames, proprio
    self.renderer = FrameRenderer(env, size, camera, fast)
    self.stack = []

  @property
  def obs_dim(self) -> int:
    size = self.renderer.size
    return size * size * 3 * self.frames + (len(PROPRIO_INDEX) if self.proprio else 0)

  def _obs(self, state: np.ndarray) -> np.ndarray:
    image = np.concatenate(self.stack, axis=-1).astype(np.float32).reshape(-1)
    if not self.proprio:
      return image
    return np.concatenate([image, proprio_of(state)])

  def reset(self, **kwargs) -> Tuple[np.ndarray, Dict[str, Any]]:
    state, info = self.env.reset(**kwargs)
    self.stack = [self.renderer.frame()] * self.frames
    return self._obs(state), dict(info, state=state)

  def step(self, action):
    state, reward, terminated, truncated, info = self.env.step(action)
    self.stack = self.stack[1:] + [self.renderer.frame()]
    return self._obs(state), reward, terminated, truncated, dict(info, state=state)

  def close(self) -> None:
    self.renderer.close()
    self.env.close()

  def __getattr__(self, name):  # The rest (action_space, render for videos, ...) is the env's.
    return getattr(self.env, name)


def proprio_of(states: np.ndarray) -> np.ndarray:
  """The robot's own state, float32 [..., 8], of Meta-World state observations [..., 39]."""
  return np.asarray(states, np.float32)[..., list(PROPRIO_INDEX)]


@functools.lru_cache(maxsize=None)
def image_env_factory(size: int, frames: int, camera: str = 'corner2', proprio: bool = False):
  """make_env(**kwargs) wrapped in PixelObservations: an evaluation's env_factory. The same
  function for the same arguments, so that evaluations reuse their environments (the pool of
  eval.evaluation is keyed by the factory). With a new one each time, every evaluation made new
  environments and two pools of them were kept: a three-seed pixel run's final evaluation reached
  23 GB resident when each environment had a renderer of its own."""
  from ld_mpc_jax.envs import metaworld_env  # pylint: disable=g-import-not-at-top
  return lambda **kwargs: PixelObservations(metaworld_env.make_env(**kwargs), size, frames,
                                            camera, proprio=proprio)
