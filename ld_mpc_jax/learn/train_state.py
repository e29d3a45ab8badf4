"""Train state and the jitted update step, built from `LearnSettings.from_config(config)`."""

import dataclasses
from typing import Any, Callable, Optional

import flax
import jax
import jax.numpy as jnp
from jax.sharding import Mesh
import ml_collections
import optax

from ld_mpc_jax.ops import build_cache, sharding
from ld_mpc_jax.model import tasks
from ld_mpc_jax.model.config_checks import check_config
from ld_mpc_jax.learn.losses import make_loss_fn
from ld_mpc_jax.model.models import build_networks, init_params_from, set_obs_normalization
from ld_mpc_jax.model.settings import LossSettings, ModelSettings


@flax.struct.dataclass
class TrainState:
  """Everything an update changes. Static hyperparameters live in the closures, not here."""
  params: Any
  opt_state: Any
  ema_params: Any
  step: jnp.ndarray


@dataclasses.dataclass(frozen=True)
class OptimSettings:
  """The optimiser's and the EMA's settings (`config.train`): what an update reads beside the
  model's and the loss's settings (ld_mpc_jax.model.settings)."""
  learning_rate: float
  warmup_steps: int
  grad_clip: float
  ema_decay: float

  @classmethod
  def from_config(cls, config: ml_collections.ConfigDict) -> 'OptimSettings':
    t = config.train
    return cls(t.learning_rate, t.warmup_steps, t.grad_clip, t.ema_decay)

  def check(self, losses: LossSettings) -> None:
    """One-line ValueErrors for an update's settings: the EMA's decay, how the loss weights and
    noises a batch (`losses.check_batch`, checked between them as ever) and the optimiser's."""
    if not 0.0 <= self.ema_decay < 1.0:
      raise ValueError(f'config.train.ema_decay must be in [0, 1), got {self.ema_decay}')
    losses.check_batch()
    if self.learning_rate <= 0 or self.grad_clip <= 0 or self.warmup_steps < 0:
      raise ValueError('config.train.learning_rate and grad_clip must be > 0 and warmup_steps '
                       f'>= 0, got {self.learning_rate}, {self.grad_clip}, {self.warmup_steps}')


@dataclasses.dataclass(frozen=True)
class LearnSettings:
  """What a fresh train state and an update read: the model's, the loss's and the optimiser's
  settings, and how the update spreads a batch (`config.train.data_parallel`, `batch_size`).
  Frozen and hashable; `from_config` runs the checks the update's builders rely on."""
  model: ModelSettings
  losses: LossSettings
  optim: OptimSettings
  data_parallel: bool
  batch_size: int

  @classmethod
  def from_config(cls, config: ml_collections.ConfigDict) -> 'LearnSettings':
    check_config(config)
    model, losses = ModelSettings.from_config(config), LossSettings.from_config(config)
    optim = OptimSettings.from_config(config)
    optim.check(losses)  # The update's own settings (check_config leaves them).
    return cls(model, losses, optim, config.train.data_parallel, config.train.batch_size)


def check_settings(settings, where: str) -> None:
  """A one-line TypeError when `settings` is a config, not its LearnSettings (what `where`, a
  builder of a train state or an update, or checkpointing.abstract_state, takes)."""
  if isinstance(settings, ml_collections.ConfigDict):
    raise TypeError(f'{where} takes LearnSettings, not a ConfigDict: pass '
                    'LearnSettings.from_config(config)')


def make_optimizer(t: OptimSettings) -> optax.GradientTransformation:
  """Adam with linear warmup to a constant rate, after global-norm gradient clipping."""
  warmup = max(t.warmup_steps, 1)
  # lr * min(1, (count + 1) / warmup): step 0 already uses lr / warmup (a schedule from 0 would
  # waste the first step), the full rate from step warmup - 1 on.
  schedule = optax.linear_schedule(t.learning_rate / warmup, t.learning_rate, warmup - 1)
  return optax.chain(optax.clip_by_global_norm(t.grad_clip), optax.adam(schedule))


def create_train_state(settings: LearnSettings, key: jax.Array,
                       obs: Optional[jnp.ndarray] = None) -> TrainState:
  """Fresh parameters of `settings` (LearnSettings.from_config(config), which checks them); the
  EMA starts as a copy of them.

  obs [N, obs_dim]: the dataset's observations, whose mean and std the encoder normalises with
  (`config.model.normalize_obs`); None leaves the identity normalisation (mean 0, std 1).
  """
  check_settings(settings, 'create_train_state')
  m = settings.model
  params = init_params_from(m, key)
  if obs is not None and m.normalize_obs:
    params = set_obs_normalization(params, obs, m.obs_mask_constant)
  tx = make_optimizer(settings.optim)

  @jax.jit  # One program, not one small compiled operation per leaf.
  def fresh(params):
    return TrainState(params=params, opt_state=tx.init(params),
                      ema_params=jax.tree_util.tree_map(jnp.copy, params),
                      step=jnp.zeros((), jnp.int32))

  return fresh(params)


def ema_update(ema_params, params, decay: float):
  """ema <- decay * ema + (1 - decay) * params, leaf by leaf."""
  return optax.incremental_update(params, ema_params, step_size=1.0 - decay)


def make_update(settings: LearnSettings, mesh: Optional[Mesh] = None) -> Callable:
  """Returns jitted update(state, batch, key) -> (state, metrics); `state` is donated.

  batch: obs [B, H+2, obs_dim], action [B, H+1, A], reward [B, H+1] (float32): windows of
  T = H + 1 steps plus one for the value bootstrap (see losses.make_loss_fn); a multi-task
  config also needs task int32 [B], task-major (ld_mpc_jax.model.tasks.multitask_loss).
  Metrics are a dict of scalars, including the gradient norm before clipping. On one device the
  same jitted function serves every config of the same settings in this process
  (ld_mpc_jax.ops.build_cache), so a second run of a config traces nothing again.

  With `settings.data_parallel` (`config.train.data_parallel`, or a `mesh` given), the same
  update is compiled for a 1-D device mesh (default: all devices, ld_mpc_jax.ops.sharding): the
  batch split along its first axis, state, key and metrics replicated. Pass the state through
  `sharding.replicate` and the batch through `sharding.shard_batch`. Otherwise it is a plain
  single-device jit.
  """
  check_settings(settings, 'make_update')
  parts = (settings.model, settings.losses, settings.optim)  # Checked by from_config.
  if mesh is None and not settings.data_parallel:
    return _jitted_update(*parts)
  mesh = sharding.make_mesh() if mesh is None else mesh
  sharding.local_batch_size(settings.batch_size, mesh)  # Raises if B % devices != 0.
  rep = sharding.replicated(mesh)
  return jax.jit(_update_fn(*parts), in_shardings=(rep, sharding.batch_sharded(mesh), rep),
                 out_shardings=(rep, rep), donate_argnums=0)


@build_cache.by_settings  # Traced once per settings value in a process.
def _jitted_update(m: ModelSettings, losses: LossSettings, t: OptimSettings) -> Callable:
  update = _update_fn(m, losses, t)
  jitted = jax.jit(update, donate_argnums=0)
  jitted.unjitted = update  # For make_multi_update.
  return jitted


def _update_fn(m: ModelSettings, losses: LossSettings, t: OptimSettings) -> Callable:
  """The unjitted update(state, batch, key) -> (state, metrics) of `make_update`."""
  nets = build_networks(m)
  loss_fn = make_loss_fn(m, losses, nets)
  if m.multitask:  # batch['task'] [B] too; one share per task (tasks.py).
    loss_fn = tasks.multitask_loss(loss_fn, m.num_tasks)
  tx = make_optimizer(t)
  decay = t.ema_decay
  h, obs_dim, act_dim = m.horizon, m.obs_dim, m.action_dim

  def update(state: TrainState, batch: dict, key: jax.Array):
    b = batch['obs'].shape[0]
    expected = {'obs': (b, h + 2, obs_dim), 'action': (b, h + 1, act_dim),
                'reward': (b, h + 1)}
    if m.multitask:
      expected['task'] = (b,)
    for name, shape in expected.items():
      if name not in batch or tuple(batch[name].shape) != shape:
        got = tuple(batch[name].shape) if name in batch else 'missing'
        raise ValueError(f'batch[{name!r}] must have shape {shape} (horizon={h}), got {got}')
    (_, metrics), grads = jax.value_and_grad(loss_fn, has_aux=True)(
        state.params, state.ema_params, batch, key)
    updates, opt_state = tx.update(grads, state.opt_state, state.params)
    params = optax.apply_updates(state.params, updates)
    metrics['grad_norm'] = optax.global_norm(grads)
    new_state = TrainState(params=params, opt_state=opt_state,
                           ema_params=ema_update(state.ema_params, params, decay),
                           step=state.step + 1)
    return new_state, metrics

  return update


def make_multi_update(settings: LearnSettings, num: int) -> Callable:
  """Returns jitted update(state, batches, key) -> (state, metrics of the last update): `num`
  updates in one call (lax.scan), batches stacked on a leading axis [num, B, ...], the i-th
  update's key fold_in(key, i). One dispatch for `num` small updates: on a 2-core CPU about
  3x fewer seconds per update at the online `:cpu` size (docs/online.md). State donated."""
  check_settings(settings, 'make_multi_update')
  update = make_update(settings).unjitted

  def multi(state, batches, key):
    def body(state, inputs):
      batch, i = inputs
      return update(state, batch, jax.random.fold_in(key, i))
    state, metrics = jax.lax.scan(body, state, (batches, jnp.arange(num)))
    return state, jax.tree_util.tree_map(lambda x: x[-1], metrics)

  jitted = jax.jit(multi, donate_argnums=0)
  jitted.unjitted = multi  # For make_seeds_update.
  return jitted


def stack_states(states):
  """One tree with a leading seed axis [N, ...] from N trees of the same structure."""
  return jax.tree_util.tree_map(lambda *xs: jnp.stack(xs), *states)


def make_seeds_update(settings: LearnSettings, num_seeds: int, per_call: int = 1) -> Callable:
  """Returns jitted update(state, batches, keys) -> (state, metrics) for `num_seeds`
  independent agents (`config.train.num_seeds`): state, batches and keys [N] carry a leading
  seed axis, and the update (`make_update`, or `per_call` updates in one call,
  `make_multi_update`, batches [N, per_call, B, ...]) is vmapped over it; metrics [N]. With one
  seed it is the unbatched update on the squeezed arguments, the same program a single run
  compiles. State donated."""
  check_settings(settings, 'make_seeds_update')
  one = (make_update(settings).unjitted if per_call == 1
         else make_multi_update(settings, per_call).unjitted)
  if num_seeds == 1:
    squeeze = lambda tree: jax.tree_util.tree_map(lambda x: x[0], tree)
    expand = lambda tree: jax.tree_util.tree_map(lambda x: x[None], tree)
    return jax.jit(lambda state, batches, keys: expand(one(squeeze(state), squeeze(batches),
                                                           keys[0])), donate_argnums=0)
  return jax.jit(jax.vmap(one), donate_argnums=0)
