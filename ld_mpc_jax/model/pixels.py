"""Pixels (issue 105): the convolutional encoder of the agent that plans in a latent of images
(`model.encoder_type='conv'`), DrQ's random-shift augmentation, and the frame-denoising dynamics
of the pixel-space baseline (`model.dynamics_type='conv_frames'`: D-MPC planning on frames).

An image observation is flat, [..., S * S * C] with S = `model.image_size` and C =
`model.image_channels` (3 per stacked RGB frame), pixel values in [0, 255], so that it travels
through datasets, buffers and `plan` as a state observation does.

- `ConvEncoder`: TD-MPC2's pixel encoder (four 32-channel convolutions: 7x7 and 5x5 and 3x3 with
  stride 2, then 3x3; ReLU; each one matmul over patches, `PatchConv`), flattened, a dense layer
  to the latent, RMS-normalised like the MLP encoder's latent. With `proprio` floats of the
  robot's own state after the pixels (`model.proprio`, as MoDem has it), a dense layer (ELU) of
  them joins the convolutions' features before that last layer.
- `random_shift`: DrQ (Kostrikov et al. 2021): each image padded by `pad` pixels (edge values)
  and cropped back at a random offset, a different one per image.
- `FrameDynamics` (the dynamics kind 'conv_frames' of ld_mpc_jax.model.dynamics): the next
  frame stack denoised from the current one, the action and the diffusion time by a small
  convolutional net at half resolution (a convolution with stride 2 over [x_t, z] stacked on
  the channels, the action and time as a FiLM scale and shift, two convolutions, nearest
  upsampling, one convolution back to C channels). With the identity encoder the planner's
  latent is then the frame stack itself, and `plan` runs unchanged in pixel space.
"""

import flax.linen as nn
import jax
import jax.numpy as jnp

from ld_mpc_jax.nets import TimeEmbedding
from ld_mpc_jax.ops.numerics import rms_normalize


def as_images(x: jnp.ndarray, size: int, channels: int) -> jnp.ndarray:
  """Flat observations [..., S * S * C] -> images [..., S, S, C] (a one-line error otherwise)."""
  if x.shape[-1] != size * size * channels:
    raise ValueError(f'image observations must be flat [..., {size} * {size} * {channels} = '
                     f'{size * size * channels}], got {x.shape}')
  return x.reshape(x.shape[:-1] + (size, size, channels))


class ConvEncoder(nn.Module):
  """Flat images [..., S * S * C] in [0, 255], then `proprio` floats of the robot's state ->
  z [..., latent_dim] (TD-MPC2's convolutions)."""
  image_size: int
  channels: int
  latent_dim: int
  features: int = 32
  proprio: int = 0
  proprio_features: int = 64

  @nn.compact
  def __call__(self, obs: jnp.ndarray) -> jnp.ndarray:
    obs, state = split_proprio(obs, self.proprio)
    x = as_images(obs, self.image_size, self.channels) / 255.0 - 0.5
    batch = x.shape[:-3]
    x = x.reshape((-1,) + x.shape[-3:])
    for i, (kernel, stride) in enumerate(((7, 2), (5, 2), (3, 2), (3, 1))):
      x = PatchConv(self.features, kernel, stride, name=f'conv_{i}')(x)
      x = nn.relu(x) if i < 3 else x
    x = x.reshape(batch + (-1,))
    if self.proprio:
      x = jnp.concatenate([x, nn.elu(nn.Dense(self.proprio_features, name='proprio')(state))], -1)
    return rms_normalize(nn.Dense(self.latent_dim, name='out')(x))


def split_proprio(obs: jnp.ndarray, proprio: int):
  """(the flat pixels, the last `proprio` floats: the robot's state, or None without them)."""
  if not proprio:
    return obs, None
  return obs[..., :-proprio], obs[..., -proprio:]


class PatchConv(nn.Module):
  """nn.Conv with a square kernel, a stride and VALID padding, computed as one matmul over the
  image's patches (im2col): nn.Conv's parameters (kernel [k, k, C, F], bias [F], the same
  initialisation) and values to float rounding; XLA:CPU's convolutions are slow for few
  channels, and with it a `:cpu_pixels` update takes 0.62x the time
  (results/benchmarks/training_pixels_patchconv_cpu.txt)."""
  features: int
  kernel: int
  stride: int

  @nn.compact
  def __call__(self, x: jnp.ndarray) -> jnp.ndarray:
    k, s, c = self.kernel, self.stride, x.shape[-1]
    kernel = self.param('kernel', nn.initializers.lecun_normal(), (k, k, c, self.features))
    bias = self.param('bias', nn.initializers.zeros_init(), (self.features,))
    rows, cols = ((x.shape[axis] - k) // s + 1 for axis in (-3, -2))
    patches = [x[..., i:i + s * (rows - 1) + 1:s, j:j + s * (cols - 1) + 1:s, :]
               for i in range(k) for j in range(k)]  # Kernel order (i, j, c).
    return jnp.concatenate(patches, -1) @ kernel.reshape(k * k * c, self.features) + bias


def random_shift(obs: jnp.ndarray, key: jax.Array, size: int, channels: int,
                 pad: int = 4, proprio: int = 0) -> jnp.ndarray:
  """DrQ's augmentation of flat images [..., S * S * C]: each image edge-padded by `pad` and
  cropped back to S x S at a random integer offset in [0, 2 pad]^2 (its own per image); the last
  `proprio` floats (the robot's state) are left as they are."""
  obs, state = split_proprio(obs, proprio)
  if state is not None:
    return jnp.concatenate([random_shift(obs, key, size, channels, pad), state], -1)
  images = as_images(obs, size, channels)
  flat = images.reshape((-1,) + images.shape[-3:])
  padded = jnp.pad(flat, ((0, 0), (pad, pad), (pad, pad), (0, 0)), mode='edge')
  offsets = jax.random.randint(key, (flat.shape[0], 2), 0, 2 * pad + 1)
  crop = lambda img, o: jax.lax.dynamic_slice(img, (o[0], o[1], 0), (size, size, channels))
  return jax.vmap(crop)(padded, offsets).reshape(obs.shape)


class FrameDynamics(nn.Module):
  """Prediction of the next flat frame stack [N, S * S * C] from its noisy version x_t, the
  diffusion time t, the current stack z and the action a."""
  image_size: int
  channels: int
  features: int = 32

  @nn.compact
  def __call__(self, x_t, t, z, a, deterministic: bool = True):
    del deterministic  # No dropout.
    s, c, f = self.image_size, self.channels, self.features
    x = jnp.concatenate([as_images(x_t, s, c), as_images(z, s, c)], axis=-1)
    h = nn.Conv(f, (3, 3), (2, 2), name='down')(x)  # [N, S / 2, S / 2, F]
    t = jnp.broadcast_to(t, x_t.shape[:-1])
    film = nn.Dense(2 * f, name='film')(jnp.concatenate([TimeEmbedding(f)(t), a], axis=-1))
    scale, shift = jnp.split(film[..., None, None, :], 2, axis=-1)
    h = nn.relu(h * (1.0 + scale) + shift)
    h = nn.relu(nn.Conv(f, (3, 3), name='mid_0')(h))
    h = nn.relu(nn.Conv(f, (3, 3), name='mid_1')(h))
    h = jnp.repeat(jnp.repeat(h, 2, axis=-3), 2, axis=-2)  # Nearest upsampling to S x S.
    out = nn.Conv(c, (3, 3), name='out')(h)
    return out.reshape(x_t.shape)
