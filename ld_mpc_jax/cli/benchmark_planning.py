r"""Planning benchmark: latency, compile time, FLOPs and fraction of peak, LD-MPC vs MPPI.

  python -m experiments.benchmark_planning                                    # everything
  python -m experiments.benchmark_planning --widths=cpu --variants=reference,fast,mppi
  python -m experiments.benchmark_planning --config=door_open.py --repeats=20 \
      --out=runs/benchmark/benchmark_planning.json

Every LD-MPC variant is a set of config overrides of the same model, run at the reference width
(the config file without preset) and/or at the `:cpu` preset's width (the trained model's size);
the rest of the config (plan settings included) comes from --config. `mppi` is the TD-MPC2-style
baseline (ld_mpc_jax.plan.mppi) with a TD-MPC2-sized MLP world model. Parameters are random (latency
does not depend on their values). Writes a JSON list of entries to --out and a markdown table
next to it (.md), again after every configuration, so that a run cut short (a device lease's time
limit, say) keeps the configurations it measured. Method: docs/benchmark.md.
"""

import dataclasses
import importlib.util
import os
import sys
import time

from absl import app, flags
import jax
import jax.numpy as jnp
from ml_collections import config_flags
import numpy as np

from ld_mpc_jax.cli import errors as cli
from ld_mpc_jax.configs import CONFIG_DIR
from ld_mpc_jax.configs.overrides import with_overrides
from ld_mpc_jax.model.config_checks import check_config
from ld_mpc_jax.model.settings import ModelSettings, PlanSettings
from benchmarks import planning
from benchmarks.hardware import device_info, measure_peak  # Shared with benchmark_training.


# name -> overrides (dotted config field -> value, or a function of the model's settings,
# ModelSettings, at the width for values that depend on it). Applied on top of --config with the
# width's model section.
_DDIM_8X2 = {'plan.action_steps': 8, 'plan.dynamics_steps': 2, 'plan.action_eta': 0.0,
             'plan.dynamics_eta': 0.0}
_DDIM_4X1 = {'plan.action_steps': 4, 'plan.dynamics_steps': 1, 'plan.action_eta': 0.0,
             'plan.dynamics_eta': 0.0}
_FAST_WARM = {**_DDIM_4X1, 'plan.num_prior_candidates': 16, 'plan.warm_start_steps': 2,
              'plan.warm_start_t': 0.5}
_SAFE = {'plan.safe_selection': True, 'plan.safe_margin': 2.0,
         'plan.safe_margin_scaling': 'expected_max'}
# Planning in observation space (D-MPC style, issue 105): the latent is the standardised
# observation (model.encoder_type='identity'), the networks' widths unchanged.
_OBS_SPACE = {'model.encoder_type': 'identity', 'model.latent_dim': lambda m: m.obs_dim,
              'model.normalize_dynamics': False}
# From pixels (issue 105): flat 64 x 64 RGB images, the latent of a convolutional encoder
# (model.encoder_type='conv'); and pixel-space planning, D-MPC on frames: the latent is the
# image (identity encoder), the dynamics a convolutional frame denoiser ('conv_frames').
_IMAGE_DIM = lambda m: m.image_size ** 2 * m.image_channels
_PIXELS = {'obs_dim': _IMAGE_DIM, 'model.encoder_type': 'conv', 'model.normalize_obs': False}
_PIXEL_SPACE = {'obs_dim': _IMAGE_DIM, 'model.encoder_type': 'identity',
                'model.latent_dim': _IMAGE_DIM, 'model.dynamics_type': 'conv_frames',
                'model.normalize_dynamics': False}
_CHEAP_OBJECTIVE = {'model.objective_blocks': lambda m: max(1, m.objective_blocks // 5)}
VARIANTS = {
    'reference': {},
    'ddim_8x2': _DDIM_8X2,
    'ddim_4x1': _DDIM_4X1,
    'ddim_8x2_k32': {**_DDIM_8X2, 'plan.num_candidates': 32},
    'ddim_8x2_cheap_obj': {**_DDIM_8X2, **_CHEAP_OBJECTIVE},
    # Previous plan re-noised to t = 0.5 and denoised in 4 steps instead of 8 from noise.
    'warm_start': {**_DDIM_8X2, 'plan.warm_start_steps': 4, 'plan.warm_start_t': 0.5},
    # The previous :cpu preset's planner: DDIM 4x1 with 16 of the 64 candidates from the actor
    # prior.
    'fast': {**_DDIM_4X1, 'plan.num_prior_candidates': 16},
    # `fast` warm-started (the :cpu preset's planner now): the shifted previous plan re-noised
    # to t = 0.5, 2 proposal steps.
    'fast_warm': _FAST_WARM,
    'fast_k32_cheap_obj': {**_DDIM_4X1, 'plan.num_candidates': 32, **_CHEAP_OBJECTIVE},
    # `fast_warm` with safe selection (margin 2 x E[max]), with one confirmation rollout of the
    # pair, and with eight (plan.confirm_draws): what the safe gate costs per call.
    'fast_warm_safe': {**_FAST_WARM, **_SAFE},
    'fast_warm_confirm': {**_FAST_WARM, **_SAFE, 'plan.safe_confirm': True},
    'fast_warm_confirm8': {**_FAST_WARM, **_SAFE, 'plan.safe_confirm': True,
                           'plan.confirm_draws': 8},
    'obs_space': _OBS_SPACE,  # `reference` and `fast_warm` planning in observation space.
    'fast_warm_obs_space': {**_FAST_WARM, **_OBS_SPACE},
    'pixels': _PIXELS,  # `reference` and `fast_warm` from pixels, in a latent and on frames.
    'fast_warm_pixels': {**_FAST_WARM, **_PIXELS},
    'pixel_space': _PIXEL_SPACE,
    'fast_warm_pixel_space': {**_FAST_WARM, **_PIXEL_SPACE},
    'mppi': None,  # The baseline; runs once, independent of the width.
}
WIDTHS = {'ref': None, 'cpu': 'cpu'}  # width name -> preset of the config file.

_CONFIG = config_flags.DEFINE_config_file(
    'config', os.path.join(CONFIG_DIR, 'door_open.py'), 'Config file (optionally :preset).',
    lock_config=True)
_REPEATS = flags.DEFINE_integer('repeats', 20, 'Timed calls per configuration (after warm-up).')
_WARMUP = flags.DEFINE_integer('warmup', 2, 'Untimed calls after compilation.')
_OUT = flags.DEFINE_string('out', 'runs/benchmark/benchmark_planning.json',
                           'JSON output; .md written beside.')
_VARIANTS = flags.DEFINE_list('variants', list(VARIANTS), f'Subset of {list(VARIANTS)}.')
_WIDTHS = flags.DEFINE_list('widths', list(WIDTHS), f'Subset of {list(WIDTHS)}.')
_PEAK_SIZE = flags.DEFINE_integer('peak_size', 2048, 'Square float32 matmul for the peak.')
_PEAK_REPEATS = flags.DEFINE_integer('peak_repeats', 10, 'Timed matmuls for the peak.')


def time_calls(fn, params, z, keys, carry_fn=None, carry=None, warmup: int = 2):
  """Compiles fn(params, z, key[, carry]) ahead of time, then times it.

  Returns (compiled executable, compile seconds, first jitted call seconds, latencies [s]).
  carry_fn(out) -> the next call's carry (the previous plan, for warm starts).
  """
  args = lambda key, c: (params, z, key) if carry is None else (params, z, key, c)
  t0 = time.perf_counter()
  compiled = fn.lower(*args(keys[0], carry)).compile()
  compile_s = time.perf_counter() - t0
  t0 = time.perf_counter()
  out = jax.block_until_ready(fn(*args(keys[0], carry)))
  first_s = time.perf_counter() - t0
  for key in keys[1:1 + warmup]:
    carry = carry_fn(out) if carry_fn else carry
    out = jax.block_until_ready(fn(*args(key, carry)))
  latencies = []
  for key in keys[1 + warmup:]:
    carry = carry_fn(out) if carry_fn else carry
    t0 = time.perf_counter()
    out = jax.block_until_ready(fn(*args(key, carry)))
    latencies.append(time.perf_counter() - t0)
  return compiled, compile_s, first_s, latencies


def width_overrides(preset) -> dict:
  """The network sizes of `preset` (a WIDTHS value) of the file --config names, as dotted
  overrides: its `model` section and its value and Q heads' `critic.hidden`."""
  sizes = load_preset(preset)
  return {**{f'model.{name}': value for name, value in sizes.model.items()},
          'critic.hidden': sizes.critic.hidden}


def resolve(overrides: dict, model: ModelSettings) -> dict:
  """A variant's overrides (a VARIANTS value) with the values that depend on the width computed
  from `model`, the settings of the model at that width."""
  return {dotted: value(model) if callable(value) else value
          for dotted, value in overrides.items()}


def run_ldmpc(name: str, width: str, model: ModelSettings, p: PlanSettings, overrides: dict,
              repeats: int, warmup: int) -> dict:
  """One LD-MPC entry: the planner `build_plan(model, p)` of a checked config (its variant at a
  width, `overrides` as resolved) on random parameters, timed and counted."""
  import ld_mpc_jax as ldmpc
  from benchmarks import flops
  from ld_mpc_jax.model.models import init_params_from
  params = init_params_from(model, jax.random.key(0))
  plan = ldmpc.build_plan(model, p)
  low, high = (0.0, 255.0) if model.images else (-1.0, 1.0)  # Pixels' range, or a state's.
  obs = np.linspace(low, high, model.obs_dim, dtype=np.float32)
  z = ldmpc.encode(params, obs)
  keys = list(jax.random.split(jax.random.key(1), 1 + warmup + repeats))
  encode_ms = time_encoder(model, params, obs, repeats, warmup)
  warm = p.warm_start_steps > 0
  carry = jnp.zeros((model.horizon, model.action_dim)) if warm else None
  compiled, compile_s, first_s, lat = time_calls(
      plan, params, z, keys, (lambda out: out.sequence) if warm else None, carry, warmup)
  args = (params, z, keys[0]) + ((carry,) if warm else ())
  if model.dynamics_type == 'conv_frames':  # The counts know the transformers only.
    nan = float('nan')
    xla = dict(plan_once=flops.compiled_flops(compiled), total=nan)
    hand = dict(proposal=nan, dynamics=nan, objective=nan, actor=nan, total=nan)
  else:
    xla = flops.xla_plan_flops(model, p, plan, args, plan_once=flops.compiled_flops(compiled))
    hand = flops.plan_flops(model, p)
  return dict(name=f'{name}/{width}', variant=name, width=width, overrides=overrides,
              model={k: getattr(model, k) for k in ('latent_dim', 'width', 'proposal_blocks',
                                                    'dynamics_blocks', 'objective_blocks')},
              num_params=ldmpc.count_params(params), num_candidates=p.num_candidates,
              steps=(f'{p.warm_start_steps if warm else p.action_steps}x{p.dynamics_steps}'),
              compile_s=compile_s, first_call_s=first_s, latencies_ms=lat,
              encode_ms=encode_ms, gflop=hand['total'] / 1e9, gflop_xla=xla['total'] / 1e9,
              gflop_xla_uncorrected=xla['plan_once'] / 1e9,
              gflop_breakdown={k: v / 1e9 for k, v in hand.items() if k != 'total'})


def time_encoder(model, params, obs: np.ndarray, repeats: int, warmup: int) -> float:
  """Median ms of the jitted encoder of `model` (ModelSettings) on one observation: a decision
  encodes, then plans."""
  from ld_mpc_jax.model.models import build_encoder
  encoder = build_encoder(model)
  fn = jax.jit(lambda p, o: encoder.apply({'params': p['encoder']}, o))
  obs = jnp.asarray(obs)
  for _ in range(1 + warmup):
    jax.block_until_ready(fn(params, obs))
  times = []
  for _ in range(repeats):
    t0 = time.perf_counter()
    jax.block_until_ready(fn(params, obs))
    times.append(time.perf_counter() - t0)
  return float(np.median(times) * 1e3)


def run_mppi(repeats: int, warmup: int) -> dict:
  from ld_mpc_jax.model import tdmpc2_world
  from ld_mpc_jax.plan import mppi
  from benchmarks import flops
  from ld_mpc_jax.model.models import count_params
  mppi_cfg, model_cfg = mppi.MPPIConfig(), tdmpc2_world.TDMPC2Config()
  params = tdmpc2_world.init_tdmpc2_params(model_cfg, jax.random.key(0))
  obs = np.linspace(-1.0, 1.0, model_cfg.obs_dim, dtype=np.float32)
  z = tdmpc2_world.TDMPC2Model(model_cfg).apply({'params': params}, obs,
                                                 method=tdmpc2_world.TDMPC2Model.encode)
  plan = mppi.make_tdmpc2_mppi(mppi_cfg, model_cfg)
  keys = list(jax.random.split(jax.random.key(1), 1 + warmup + repeats))
  carry = jnp.zeros((mppi_cfg.horizon, mppi_cfg.action_dim))
  compiled, compile_s, first_s, lat = time_calls(plan, params, z, keys, lambda out: out.mean,
                                                 carry, warmup)
  xla = flops.xla_mppi_flops(plan, (params, z, keys[0], carry),
                             mppi.make_tdmpc2_value_fn(model_cfg), params, mppi_cfg,
                             plan_once=flops.compiled_flops(compiled))
  hand = flops.tdmpc2_mppi_flops(mppi_cfg, model_cfg)
  return dict(name='mppi', variant='mppi', width='tdmpc2-5M',
              overrides={'mppi': dataclasses.asdict(mppi_cfg),
                         'model': dataclasses.asdict(model_cfg)},
              num_params=count_params(params), num_candidates=mppi_cfg.num_samples,
              steps=f'{mppi_cfg.iterations} it', compile_s=compile_s, first_call_s=first_s,
              latencies_ms=lat, gflop=hand['total'] / 1e9, gflop_xla=xla['total'] / 1e9,
              gflop_xla_uncorrected=xla['plan_once'] / 1e9)


def load_preset(preset):
  """get_config(preset) of the file --config names."""
  path = config_flags.get_config_filename(flags.FLAGS['config']).partition(':')[0]
  spec = importlib.util.spec_from_file_location('_benchmark_config', path)
  module = importlib.util.module_from_spec(spec)
  spec.loader.exec_module(module)
  return module.get_config(preset)


def main(argv):
  del argv
  with cli.one_line_errors():
    cli.check_subset('variants', _VARIANTS.value, VARIANTS)
    cli.check_subset('widths', _WIDTHS.value, WIDTHS)
    if _REPEATS.value < 1:
      raise ValueError(f'--repeats must be >= 1, got {_REPEATS.value}')
    cli.check_new_output(_OUT.value, overwrite=True)  # A benchmark replaces its last result.
  spec = config_flags.get_config_filename(flags.FLAGS['config'])
  try:
    if not os.path.exists(spec.partition(':')[0]):
      raise FileNotFoundError(spec)
    base = _CONFIG.value
  except OSError as err:  # ml_collections defers a config file's failure to here.
    cli.fail(cli.config_file_error('--config', spec, err))
  device = device_info()
  print(f"device: {device['name']}; load average {device['loadavg_1min_at_start']:.2f}")
  peak = measure_peak(_PEAK_SIZE.value, _PEAK_REPEATS.value)
  print(f'peak: {peak:.1f} GFLOP/s ({_PEAK_SIZE.value}^2 float32 matmul)')
  entries = []
  total = sum(1 if name == 'mppi' else len(_WIDTHS.value) for name in _VARIANTS.value)

  def add(entry):
    entries.append(entry)
    print(f"[{len(entries)}/{total}] {entry['name']}: median "
          f"{np.median(entry['latencies_ms']) * 1e3:.1f} ms, compile "
          f"{entry['compile_s']:.1f} s, {entry['gflop']:.2f} GFLOP (XLA {entry['gflop_xla']:.2f})",
          flush=True)
    planning.write_partial(_OUT.value, entries, peak, device)  # A cut run keeps these.

  for name in _VARIANTS.value:
    if name == 'mppi':
      add(run_mppi(_REPEATS.value, _WARMUP.value))
      continue
    if name == 'warm_start' and 'warm_start_steps' not in base.plan:
      print('skipping warm_start: this config has no plan.warm_start_steps')
      total -= len(_WIDTHS.value)
      continue
    for width in _WIDTHS.value:  # The variant's overrides on --config at the width's sizes.
      sized = with_overrides(base, width_overrides(WIDTHS[width]))
      resolved = resolve(VARIANTS[name], ModelSettings.from_config(sized))
      config = with_overrides(sized, resolved)
      check_config(config)
      add(run_ldmpc(name, width, ModelSettings.from_config(config),
                    PlanSettings.from_config(config), resolved, _REPEATS.value, _WARMUP.value))
  peak_end = measure_peak(_PEAK_SIZE.value, _PEAK_REPEATS.value)
  print(f'peak at the end: {peak_end:.1f} GFLOP/s')
  print(planning.markdown(planning.write_partial(_OUT.value, entries, max(peak, peak_end), device,
                                                quiet=False)))
