"""Pixels (issue 105, ld_mpc_jax.model.pixels): DrQ's random shift, the convolutional encoder of the
latent agent from images, and the frame-denoising dynamics of the pixel-space planner. Tiny
images and smoke widths."""

import ctypes.util
import os

import flax.linen as nn
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import ld_mpc_jax as ldmpc
from ld_mpc_jax.configs.overrides import with_overrides
from ld_mpc_jax.learn import losses
from ld_mpc_jax.model import dynamics, models, pixels
from ld_mpc_jax.model.settings import LossSettings, ModelSettings


def test_random_shift_crops_the_edge_padded_image_at_an_offset_of_its_own():
  rng = np.random.default_rng(0)
  images = rng.uniform(0, 255, (16, 6, 6, 2)).astype(np.float32)
  flat = jnp.asarray(images.reshape(16, -1))
  assert np.array_equal(pixels.random_shift(flat, jax.random.key(0), 6, 2, pad=0), flat)
  out = np.asarray(pixels.random_shift(flat, jax.random.key(1), 6, 2, pad=2)).reshape(images.shape)
  padded = np.pad(images, ((0, 0), (2, 2), (2, 2), (0, 0)), mode='edge')
  offsets = []
  for img, pad_img in zip(out, padded):
    found = [(i, j) for i in range(5) for j in range(5)
             if np.array_equal(img, pad_img[i:i + 6, j:j + 6])]
    assert found, 'not a crop of the padded image'
    offsets.append(found[0])
  assert len(set(offsets)) > 4  # Each image its own offset.


@pytest.mark.parametrize('kernel, stride, size', [(7, 2, 13), (5, 2, 12), (3, 1, 5)])
def test_patch_conv_is_nn_conv_with_its_parameters(kernel, stride, size):
  """PatchConv: nn.Conv's parameter tree and initial values (the same names and keys) and its
  outputs and gradients to float rounding, odd and even sizes, over leading batch axes."""
  x = jnp.asarray(np.random.default_rng(0).normal(size=(2, 3, size, size, 4)), jnp.float32)
  conv = nn.Conv(6, (kernel, kernel), (stride, stride), padding='VALID')
  patch = pixels.PatchConv(6, kernel, stride)
  p_conv, p_patch = conv.init(jax.random.key(3), x), patch.init(jax.random.key(3), x)
  assert jax.tree.structure(p_conv) == jax.tree.structure(p_patch)
  for a, b in zip(jax.tree.leaves(p_conv), jax.tree.leaves(p_patch)):
    assert np.array_equal(a, b)
  p = jax.tree.map(lambda a: a + 0.1, p_conv)  # A bias that is not zero.
  np.testing.assert_allclose(patch.apply(p, x), conv.apply(p, x), rtol=1e-5, atol=1e-5)
  loss = lambda m: lambda p, x: jnp.sum(jnp.sin(m.apply(p, x)))
  for a, b in zip(jax.tree.leaves(jax.grad(loss(patch), argnums=(0, 1))(p, x)),
                  jax.tree.leaves(jax.grad(loss(conv), argnums=(0, 1))(p, x))):
    np.testing.assert_allclose(a, b, rtol=1e-4, atol=1e-4)


@pytest.fixture(scope='module')
def pixel_config():
  from ld_mpc_jax.configs import door_open  # pylint: disable=g-import-not-at-top
  return with_overrides(door_open.get_config('smoke'), {
      'obs_dim': 40 * 40 * 3, 'model.image_size': 40, 'model.encoder_type': 'conv',
      'model.normalize_obs': False})


def test_the_conv_encoder_maps_images_to_the_latent_sphere(pixel_config):
  params = ldmpc.init_params(pixel_config, jax.random.key(0))
  assert set(params['encoder']) == {'conv_0', 'conv_1', 'conv_2', 'conv_3', 'out'}
  obs = np.random.default_rng(1).uniform(0, 255, (3, 40 * 40 * 3)).astype(np.float32)
  z = np.asarray(ldmpc.encode(params, obs))
  assert z.shape == (3, pixel_config.model.latent_dim)
  np.testing.assert_allclose(np.sqrt(np.mean(z ** 2, axis=-1)), 1.0, rtol=1e-4)
  assert not np.allclose(z[0], z[1])  # Different images, different latents.
  with pytest.raises(ValueError, match='flat images'):
    ldmpc.encode(params, obs[:, :-3])
  out = ldmpc.make_plan(pixel_config)(params, z[0], jax.random.key(2))  # plan, unchanged.
  assert out.action.shape == (4,) and np.all(np.abs(np.asarray(out.action)) <= 1.0)


def test_training_from_pixels_reaches_the_convolutions(pixel_config):
  m = ModelSettings.from_config(pixel_config)
  loss_fn = jax.jit(losses.make_loss_fn(m, LossSettings.from_config(pixel_config),
                                        models.build_networks(m)))
  params = ldmpc.init_params(pixel_config, jax.random.key(0))
  rng, h = np.random.default_rng(0), pixel_config.horizon
  batch = {'obs': jnp.asarray(rng.uniform(0, 255, (2, h + 2, 40 * 40 * 3)), jnp.float32),
           'action': jnp.asarray(rng.uniform(-1, 1, (2, h + 1, 4)), jnp.float32),
           'reward': jnp.asarray(rng.uniform(0, 1, (2, h + 1)), jnp.float32)}
  grads, metrics = jax.grad(loss_fn, has_aux=True)(params, params, batch, jax.random.key(1))
  assert np.isfinite(float(metrics['loss']))
  assert float(jnp.abs(grads['encoder']['conv_0']['kernel']).max()) > 0


def test_the_robots_state_beside_the_pixels_reaches_the_latent_and_is_not_shifted(pixel_config):
  """model.proprio: 8 floats after the pixels, through their own dense layer into the latent;
  DrQ's shift moves the pixels only."""
  config = with_overrides(pixel_config, {'model.proprio': True, 'obs_dim': 40 * 40 * 3 + 8})
  ldmpc.validate_config(config)
  params = ldmpc.init_params(config, jax.random.key(0))
  assert params['encoder']['proprio']['kernel'].shape == (8, 64)
  rng = np.random.default_rng(1)
  obs = np.concatenate([rng.uniform(0, 255, (2, 40 * 40 * 3)), rng.normal(size=(2, 8))], -1)
  obs = obs.astype(np.float32)
  moved = obs.copy()
  moved[:, -8:] += 0.5  # The same pictures, the hand elsewhere.
  z, z_moved = np.asarray(ldmpc.encode(params, obs)), np.asarray(ldmpc.encode(params, moved))
  assert z.shape == (2, config.model.latent_dim) and not np.allclose(z, z_moved, atol=1e-3)
  shifted = np.asarray(pixels.random_shift(jnp.asarray(obs), jax.random.key(3), 40, 3, pad=4,
                                            proprio=8))
  assert np.array_equal(shifted[:, -8:], obs[:, -8:])
  assert not np.array_equal(shifted[:, :-8], obs[:, :-8])
  with pytest.raises(ValueError, match=r'\+ 8 \(model.proprio\) = 4808'):
    ldmpc.validate_config(with_overrides(config, {'obs_dim': 40 * 40 * 3}))
  with pytest.raises(ValueError, match="encoder_type='conv' only"):
    ldmpc.validate_config(with_overrides(door_open_smoke(), {'model.proprio': True}))


def door_open_smoke():
  from ld_mpc_jax.configs import door_open  # pylint: disable=g-import-not-at-top
  return door_open.get_config('smoke')


def test_the_proprio_indices_are_the_robots_state_the_model_counts():
  from ld_mpc_jax.envs.pixels import PROPRIO_INDEX, proprio_of  # pylint: disable=g-import-not-at-top
  from ld_mpc_jax.model.settings import PROPRIO_DIM  # pylint: disable=g-import-not-at-top
  assert len(PROPRIO_INDEX) == PROPRIO_DIM
  state = np.arange(39, dtype=np.float32)
  assert proprio_of(state).tolist() == [0, 1, 2, 3, 18, 19, 20, 21]


@pytest.fixture(scope='module')
def frames_config():
  from ld_mpc_jax.configs import door_open  # pylint: disable=g-import-not-at-top
  return with_overrides(door_open.get_config('smoke'), {
      'obs_dim': 8 * 8 * 3, 'model.image_size': 8, 'model.latent_dim': 8 * 8 * 3,
      'model.encoder_type': 'identity', 'model.dynamics_type': 'conv_frames',
      'model.normalize_dynamics': False})


def test_pixel_space_planning_denoises_frames_and_learns_them(frames_config):
  params = ldmpc.init_params(frames_config, jax.random.key(0))
  assert set(params['dynamics']) >= {'down', 'film', 'mid_0', 'mid_1', 'out'}
  z = ldmpc.encode(params, np.zeros(8 * 8 * 3, np.float32))
  out = ldmpc.make_plan(frames_config)(params, z, jax.random.key(1))
  assert out.candidates.shape[0] == frames_config.plan.num_candidates
  assert np.all(np.isfinite(np.asarray(out.scores)))
  # The next frame is the current one rolled by one row: the kind's loss learns it from z.
  import optax  # pylint: disable=g-import-not-at-top
  m, kind = ModelSettings.from_config(frames_config), dynamics.DYNAMICS.get('conv_frames')
  module = kind.build(m)
  params = {'dynamics': module.init(jax.random.key(0), *kind.init_args(m))['params']}
  rng, h = np.random.default_rng(0), frames_config.horizon
  frames = rng.normal(size=(16, 8, 8, 3)).astype(np.float32)
  z = np.stack([np.roll(frames, t, axis=1) for t in range(h + 2)], axis=1)
  z = jnp.asarray(z.reshape(16, h + 2, -1))
  action = jnp.asarray(rng.uniform(-1, 1, (16, h + 1, 4)), jnp.float32)
  tx = optax.adam(3e-3)

  @jax.jit
  def step(params, opt, key):
    loss, grads = jax.value_and_grad(
        lambda p: kind.loss(m, module, p, z, action, key, {}))(params)
    updates, opt = tx.update(grads, opt)
    return optax.apply_updates(params, updates), opt, loss

  opt, losses_ = tx.init(params), []
  for i in range(100):
    params, opt, loss = step(params, opt, jax.random.key(i))
    losses_.append(float(loss))
  assert np.mean(losses_[-10:]) < 0.5 * np.mean(losses_[:10])


@pytest.mark.parametrize('overrides,match', [
    ({'model.encoder_type': 'conv', 'model.normalize_obs': False}, 'obs_dim must be'),
    ({'model.encoder_type': 'conv', 'obs_dim': 12288}, 'normalize_obs=False'),
    ({'model.dynamics_type': 'conv_frames', 'obs_dim': 12288}, "encoder_type='identity'"),
    ({'model.encoder_type': 'conv', 'model.normalize_obs': False, 'model.image_size': 32,
      'obs_dim': 32 * 32 * 3}, 'image_size >= 39'),
    ({'model.encoder_type': 'identity', 'model.dynamics_type': 'conv_frames', 'obs_dim': 147,
      'model.latent_dim': 147, 'model.image_size': 7, 'model.normalize_dynamics': False}, 'even'),
    ({'model.encoder_type': 'conv', 'model.normalize_obs': False, 'obs_dim': 12288,
      'eval.obs_noise': 0.1}, 'rendered without it'),
])
def test_bad_pixel_settings_fail_in_one_line(overrides, match):
  from ld_mpc_jax.configs import door_open  # pylint: disable=g-import-not-at-top
  with pytest.raises(ValueError, match=match):
    ldmpc.validate_config(with_overrides(door_open.get_config('smoke'), overrides))


# Offscreen MuJoCo rendering: tests/conftest.py sets MUJOCO_GL=osmesa; .ci/run installs the library.
NEEDS_RENDERING = pytest.mark.skipif(
    os.environ.get('MUJOCO_GL') != 'osmesa' or ctypes.util.find_library('OSMesa') is None,
    reason='offscreen MuJoCo rendering needs MUJOCO_GL=osmesa set before the tests start and '
    'libosmesa6 (apt-get install -y libosmesa6)')


@NEEDS_RENDERING
def test_pixel_observations_stack_the_last_frames_flat():
  from ld_mpc_jax.envs import metaworld_env  # pylint: disable=g-import-not-at-top
  from ld_mpc_jax.envs.pixels import PixelObservations  # pylint: disable=g-import-not-at-top
  env = PixelObservations(metaworld_env.make_env('door-open-v3', seed=0), size=16, frames=2)
  obs, info = env.reset(seed=1)
  assert obs.shape == (env.obs_dim,) == (16 * 16 * 3 * 2,) and obs.dtype == np.float32
  assert info['state'].shape == (39,) and 0 <= obs.min() and obs.max() <= 255
  frames = obs.reshape(16, 16, 2, 3)  # [S, S, frames, RGB]: the stack is on the channels.
  assert np.array_equal(frames[:, :, 0], frames[:, :, 1])  # At reset the first frame fills it.
  for _ in range(8):
    obs, _, _, _, info = env.step(np.array([1.0, -1.0, 1.0, 1.0], np.float32))
  frames = obs.reshape(16, 16, 2, 3)
  assert not np.array_equal(frames[:, :, 0], frames[:, :, 1])  # The arm moved between them.
  env.close()
  env = PixelObservations(metaworld_env.make_env('door-open-v3', seed=0), size=16, frames=1,
                          proprio=True)
  obs, info = env.reset(seed=1)
  assert obs.shape == (env.obs_dim,) == (16 * 16 * 3 + 8,)
  np.testing.assert_array_equal(obs[-8:], info['state'][[0, 1, 2, 3, 18, 19, 20, 21]].astype(np.float32))
  env.close()


def test_evaluations_of_a_pixel_model_reuse_one_environment_factory():
  from ld_mpc_jax.envs.pixels import image_env_factory  # pylint: disable=g-import-not-at-top
  assert image_env_factory(16, 1, proprio=True) is image_env_factory(16, 1, proprio=True)
  assert image_env_factory(16, 1) is not image_env_factory(16, 2)


@NEEDS_RENDERING
def test_the_environments_of_a_task_share_one_renderer_and_draw_their_own_state():
  import mujoco  # pylint: disable=g-import-not-at-top
  from ld_mpc_jax.envs import metaworld_env, pixels  # pylint: disable=g-import-not-at-top
  make = lambda seed: metaworld_env.make_env('door-open-v3', seed=seed, random_goals=True)
  before = len(pixels._RENDERERS)  # Other tests' environments left open, if any.
  envs = [pixels.PixelObservations(make(s), size=16, frames=1) for s in (0, 1)]
  obs = [e.reset(seed=s)[0] for s, e in enumerate(envs)]
  assert envs[0].renderer.renderer is envs[1].renderer.renderer
  assert len(pixels._RENDERERS) == before + 1
  base = envs[1].env.unwrapped  # Its door elsewhere: the models differ in KINEMATIC_FIELDS only.
  assert not np.array_equal(envs[0].env.unwrapped.model.body_pos, base.model.body_pos)
  assert not np.array_equal(obs[0], obs[1])
  own = mujoco.Renderer(base.model, 16, 16)  # What the second one draws with a renderer of its own.
  own.update_scene(base.data, camera='corner2')
  for flag in pixels.SLOW_FLAGS:
    own.scene.flags[getattr(mujoco.mjtRndFlag, flag)] = False
  np.testing.assert_array_equal(obs[1], own.render().reshape(-1).astype(np.float32))
  own.close()
  envs[0].close()
  envs[0].close()  # Twice is once: the second environment still draws.
  assert np.array_equal(envs[1].step(np.zeros(4, np.float32))[0].shape, obs[1].shape)
  envs[1].close()
  assert len(pixels._RENDERERS) == before


@NEEDS_RENDERING
def test_an_image_dataset_replays_the_collected_episodes(tmp_path, monkeypatch):
  from ld_mpc_jax.data import collection, dataset, pixels as data_pixels, replay  # pylint: disable=g-import-not-at-top
  ds = collection.collect('door-open-v3', 'medium', 2, seed=0, max_episode_steps=20,
                          progress=False)
  path = str(tmp_path / 'door.npz')
  images = data_pixels.get_or_render(ds, path, 8, 1, progress=False)
  assert images.observations.shape == (ds.num_transitions + ds.num_episodes, 8 * 8 * 3)
  assert images.observations.dtype == np.uint8 and images.observations.max() > 0
  assert np.array_equal(images.actions, ds.actions) and np.array_equal(images.rewards, ds.rewards)
  batch = replay.ReplayBuffer(images, seq_len=3, seed=0).sample(4)
  assert batch['obs'].dtype == np.float32 and batch['obs'].shape == (4, 3, 8 * 8 * 3)
  monkeypatch.setattr(data_pixels, 'render_dataset', lambda *a, **k: pytest.fail('rendered again'))
  assert np.array_equal(data_pixels.get_or_render(ds, path, 8, 1).observations,
                        images.observations)  # From the file beside the state dataset's.
  both = data_pixels.with_proprio(images, ds)  # The robot's state after the frames, float32.
  assert both.observations.shape == (images.observations.shape[0], 8 * 8 * 3 + 8)
  assert np.array_equal(both.observations[:, :-8], images.observations)
  assert np.array_equal(both.observations[:, -8:], ds.observations[:, [0, 1, 2, 3, 18, 19, 20, 21]])
  ds.actions[1] = -ds.actions[1]  # Other actions: the replay leaves the stored states.
  monkeypatch.undo()
  with pytest.raises(dataset.DatasetError, match='replays to other states'):
    data_pixels.render_dataset(ds, 8, 1)


@NEEDS_RENDERING
def test_an_interrupted_rendering_goes_on_where_it_stopped(tmp_path, monkeypatch):
  from ld_mpc_jax.data import collection, pixels as data_pixels  # pylint: disable=g-import-not-at-top
  from ld_mpc_jax.envs.pixels import PixelObservations  # pylint: disable=g-import-not-at-top
  ds = collection.collect('door-open-v3', 'medium', 3, seed=0, max_episode_steps=10,
                          progress=False)
  whole = data_pixels.render_dataset(ds, 8, 1)
  partial, reset, resets = str(tmp_path / 'px.partial.npz'), PixelObservations.reset, []

  def interrupted(self, **kw):
    if len(resets) == 2:  # The third episode: after two were saved.
      raise KeyboardInterrupt
    resets.append(kw['seed'])
    return reset(self, **kw)
  monkeypatch.setattr(PixelObservations, 'reset', interrupted)
  with pytest.raises(KeyboardInterrupt):
    data_pixels.render_dataset(ds, 8, 1, partial=partial, save_every=1)
  monkeypatch.setattr(PixelObservations, 'reset', lambda self, **kw: (resets.append(kw['seed']),
                                                                    reset(self, **kw))[1])
  resumed = data_pixels.render_dataset(ds, 8, 1, partial=partial, save_every=1)
  assert len(resets) == 3  # Only the third episode was rendered again.
  assert np.array_equal(resumed.observations, whole.observations)
  other = data_pixels.render_dataset(ds, 8, 1, camera='corner', partial=partial)  # Other data.
  assert len(resets) == 6 and other.observations.shape == whole.observations.shape


_POOLED_AT_EXIT = """
from ld_mpc_jax.eval import evaluation
from ld_mpc_jax.envs.pixels import image_env_factory
for env in evaluation._envs(image_env_factory(16, 1), 2, dict(task='door-open-v3', seed=0)):
  env.reset(seed=1)
print('kept')
"""


@NEEDS_RENDERING
def test_renderers_an_evaluation_pool_keeps_close_quietly_at_exit():
  """The pooled environments live until the process ends: their shared renderer closes at exit
  (envs.pixels.close_renderers), not in the interpreter's teardown, which printed TypeErrors."""
  import subprocess  # pylint: disable=g-import-not-at-top
  import sys  # pylint: disable=g-import-not-at-top
  repo = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
  done = subprocess.run([sys.executable, '-c', _POOLED_AT_EXIT], cwd=repo, capture_output=True,
                        text=True, timeout=300, env=dict(os.environ, PYTHONPATH=repo))
  assert done.returncode == 0 and done.stdout.strip() == 'kept', done.stderr[-2000:]
  assert 'Exception ignored' not in done.stderr and 'TypeError' not in done.stderr, done.stderr
