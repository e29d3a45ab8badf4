"""Policies for the environment loop: the planner, the actor prior, the proposal alone, and MPPI
on the learned model (config.mppi; the TD-MPC2-style baseline).

Each is one jitted function of (params, obs, key, t, prev) that encodes the observation and
acts, so a decision costs one dispatch. Keys follow a fixed schedule: episode e acts at decision
t with fold_in(fold_in(key(seed), e.reset_seed), t), whether it runs alone (`make_policy`, the
`policy(obs) -> action` interface) or with others in lockstep (`BatchAgentPolicy`, one jitted
call for N environments), so the two give the same episodes. With a device mesh
(`config.eval.data_parallel`), the N environments are split over the devices
(`jax.shard_map`), each device acting for its share with replicated parameters; every
environment keeps its keys, so the actions are those of a single device.
"""

from typing import Callable, Optional, Sequence, Tuple

import jax
import jax.numpy as jnp
from jax.sharding import Mesh, PartitionSpec
import numpy as np

from ld_mpc_jax.ops import sharding
from ld_mpc_jax.plan.modes import (  # noqa: F401 (the modes' names, re-exported)
    MODES, NO_PLAN_INFO, POLICY_MODES, ActSettings, PolicyMode, carried_sequence, make_act_fn,
    uses_prev)

def make_act(settings: ActSettings, mode: str = 'plan') -> Callable:
  """Returns jitted act(params, obs [obs_dim], key, t [], prev, noise=0.0, intrinsic=None) ->
  (action [A], carry, info [7] float32: NO_PLAN_INFO's fields). `noise` and `intrinsic`
  (objective.Intrinsic; acting only) are traced: annealing them never recompiles.

  The decision's key is fold_in(key, t). `prev` is the previous decision's carry (or None at
  the start of an episode); only the planner with `plan.warm_start_steps` > 0 or
  `plan.fallback_drop` > 0 and MPPI (its Gaussian mean) use it. `carry` is what to pass as the
  next `prev`: the sequence [H, A], or for the planner with `plan.fallback_drop` > 0 the pair
  (sequence, planner.Guard).
  """
  act = make_act_fn(settings, mode)
  jitted = jax.jit(lambda params, obs, key, t, prev, noise, intrinsic: act(
      params, obs, jax.random.fold_in(key, t), prev, noise, intrinsic))
  return lambda params, obs, key, t, prev, noise=0.0, intrinsic=None: jitted(
      params, obs, key, t, prev, float32(noise), float32_tree(intrinsic))


def float32_tree(tree):
  """Scalars as float32 arrays (Python floats and NumPy scalars trace alike: one compile).

  NumPy, not jnp: an eager jnp conversion is an operation on the default device, which waits
  there behind every update already dispatched, and so would stall the acting loop that the
  updates are meant to overlap (measured with py-spy: 38% of the main thread of a 3-seed run)."""
  return jax.tree_util.tree_map(float32, tree)


def float32(x):
  """x as a float32 scalar: NumPy for Python and NumPy numbers, jnp for JAX arrays and tracers."""
  return jnp.asarray(x, jnp.float32) if isinstance(x, jax.Array) else np.asarray(x, np.float32)


def episode_keys(seed: int, reset_seeds: Sequence[int]) -> jax.Array:
  """[N] keys: fold_in(key(seed), reset_seed) for each episode."""
  seeds = jnp.asarray(np.asarray(reset_seeds, np.int64).astype(np.uint32))
  return jax.vmap(jax.random.fold_in, in_axes=(None, 0))(jax.random.key(seed), seeds)


def make_batch_act(settings: ActSettings, mode: str = 'plan', chunk: Optional[int] = None,
                   mesh: Optional[Mesh] = None) -> Callable:
  """Returns jitted act(params, obs [N, obs_dim], keys [N], t [], prev, active [N], noise [],
  intrinsic=None).

  -> (actions [N, A], sequences [N, H, A], infos [N, 6]): `jax.lax.map` of the
  single-environment act over the N environments, `chunk` at a time under `jax.vmap` (None: all N in one vmap). Inactive
  environments (episode over) return zeros; with chunk = 1 they are skipped (lax.cond), under a
  vmap they are computed and discarded. `prev` is [N, H, A] or None (the first decision).
  With a `mesh` (sharding.make_mesh), the N environments are split over its devices
  (`jax.shard_map`; N is padded with inactive rows to a multiple of the device count) and each
  device maps over its share as above; `params` should be replicated (sharding.replicate).
  """
  act = make_act_fn(settings, mode)

  def one(params, t, knobs, has_prev, inputs):  # knobs: (noise, intrinsic), acting's.
    obs, key, prev, active = inputs
    key = jax.random.fold_in(key, t)
    prev = prev if has_prev else None
    run = lambda: act(params, obs, key, prev, *knobs)
    zeros = lambda: jax.tree_util.tree_map(jnp.zeros_like, jax.eval_shape(run))
    return jax.lax.cond(active, run, zeros)

  def local_act(has_prev, params, obs, keys, t, prev, active, knobs):
    n = obs.shape[0]
    return jax.lax.map(lambda x: one(params, t, knobs, has_prev, x), (obs, keys, prev, active),
                       batch_size=min(chunk or n, n))

  def batch_act(params, obs, keys, t, prev, active, noise=0.0, intrinsic=None):
    knobs = (float32(noise), float32_tree(intrinsic))
    n = obs.shape[0]
    has_prev = prev is not None
    if not has_prev:  # Placeholders of the carry's shapes (the first decision ignores them).
      carry = jax.eval_shape(lambda: act(params, obs[0], keys[0], None, *knobs)[1])
      prev = jax.tree_util.tree_map(lambda x: jnp.zeros((n,) + x.shape, x.dtype), carry)
    if mesh is None:
      return local_act(has_prev, params, obs, keys, t, prev, active, knobs)
    pad = -n % mesh.size  # Inactive rows, so that every device gets the same share.
    grow = lambda x: jnp.concatenate([x, jnp.repeat(x[-1:], pad, axis=0)]) if pad else x
    obs, keys, prev = grow(obs), grow(keys), jax.tree_util.tree_map(grow, prev)
    active = jnp.concatenate([active, jnp.zeros(pad, bool)])
    split, whole = PartitionSpec(sharding.BATCH_AXIS), PartitionSpec()
    # check_vma off: the replication check of shard_map does not follow the lax.cond above.
    out = jax.shard_map(lambda *args: local_act(has_prev, *args), mesh=mesh,
                        in_specs=(whole, split, split, whole, split, split, whole),
                        out_specs=split, check_vma=False)(params, obs, keys, t, prev, active,
                                                          knobs)
    return jax.tree_util.tree_map(lambda x: x[:n], out)

  return jax.jit(batch_act)


_BATCH_ACTS = {}


def _compile_single(act, params, obs: np.ndarray, key, warm: bool) -> None:
  """Compiles a `make_act` function's first (cold) and later (warm) decisions."""
  obs = jnp.asarray(obs, jnp.float32)
  _, sequence, _ = act(params, obs, key, 0, None)
  jax.block_until_ready(act(params, obs, key, 1, sequence if warm else None))


class BatchAgentPolicy:
  """N environments in lockstep with one jitted call per decision (an evaluation BatchPolicy).

  Each environment keeps its own previous sequence (warm start), cleared when a wave of
  episodes starts, and its own key schedule (module docstring). `chunk` as in `make_batch_act`;
  `chunk` = 0 instead calls the single-environment act once per active environment (the
  fastest for the planner on a 2-core CPU, where a K = 64 plan already fills the cores). With a
  `mesh`, the environments are split over its devices (`make_batch_act`), and `chunk` = 0 maps
  one environment at a time on each device. With `keep_sequences` (the 'plan' mode), each call
  also leaves the planner's chosen sequences in `last_sequences` [N, H, A] (online acting under
  `loss.act_target='planned'`).
  """

  def __init__(self, settings: ActSettings, params, mode: str = 'plan', seed: int = 0,
               chunk: Optional[int] = None, mesh: Optional[Mesh] = None,
               action_noise: float = 0.0, intrinsic=None, keep_sequences: bool = False):
    self.seed, self.mesh = seed, mesh
    self.sequence_of = (lambda carry: carried_sequence(settings.plan, carry)) if (
        keep_sequences) else None
    self.last_sequences = None
    self.set_params(params)
    if mesh is not None:
      chunk = 1 if chunk == 0 else chunk
    self.warm = uses_prev(settings.plan, mode)
    self.per_env = chunk == 0  # One jitted call per environment (the single-env act).
    self.action_dim = settings.model.action_dim
    self.sequence_shape = (settings.model.horizon, self.action_dim)  # A planned sequence [H, A].
    # One jitted function per setting, compiled once per process; the task name is no setting,
    # so the tasks of a multi-task agent (tasks.bind) share it.
    key = (settings, mode, chunk, mesh)
    if key not in _BATCH_ACTS:
      _BATCH_ACTS[key] = (make_act(settings, mode) if self.per_env
                          else make_batch_act(settings, mode, chunk, mesh))
    self.act = _BATCH_ACTS[key]
    self.keys = self.prev = self._sliced = None
    # The executed action's noise std and the planner's objective.Intrinsic (acting only).
    self.action_noise, self.intrinsic = action_noise, intrinsic
    self.last_info = None  # [N, 7] float32 of the last decision (NO_PLAN_INFO's fields).

  def set_params(self, params) -> None:
    """The parameters to act with from now on (replicated over the mesh, if any; copied to
    the devices only when they are new parameters)."""
    if self.mesh is None:
      self.params = params
    elif params is not getattr(self, '_source', None):
      self._source, self.params = params, self.prepare(params)

  def prepare(self, params):
    """`params` as `decide` takes them: replicated over the mesh, if any."""
    return params if self.mesh is None else sharding.replicate(params, self.mesh)

  def start(self, episodes) -> None:
    self.keys = episode_keys(self.seed, [ep.reset_seed for ep in episodes])
    self.prev = None
    # Each environment's keys, sliced once here: slicing at each decision would be an eager
    # operation, waiting behind the updates dispatched to the device.
    self._sliced = ([self.keys[i] for i in range(self.keys.shape[0])] if self.per_env
                    else None)

  def warmup(self, obs: np.ndarray) -> None:
    """Compiles the first (cold) and later (warm) decisions for this batch size."""
    if self.per_env:
      _compile_single(self.act, self.params, obs[0], episode_keys(self.seed, [0])[0], self.warm)
      return
    obs = jnp.asarray(obs, jnp.float32)
    keys = episode_keys(self.seed, np.arange(obs.shape[0]))
    active = jnp.ones(obs.shape[0], bool)
    knobs = (self.action_noise, self.intrinsic)
    _, seq, _ = self.act(self.params, obs, keys, 0, None, active, *knobs)
    jax.block_until_ready(self.act(self.params, obs, keys, 1, seq if self.warm else None, active,
                                   *knobs))

  def __call__(self, obs: np.ndarray, t: int, active: np.ndarray) -> np.ndarray:
    actions, self.last_info, sequences, self.prev = self.decide(self.params, obs, t, active,
                                                                self.prev)
    if sequences is not None:
      self.last_sequences = sequences
    return actions

  def decide(self, params, obs: np.ndarray, t: int, active: np.ndarray, prev):
    """One decision of the wave `start` began, writing nothing on the policy: (actions [N, A],
    infos [N, 6], the planner's chosen sequences [N, H, A] or None, the warm-start carry to
    pass to the next decision). `params` as `prepare` gives them; `prev`: None at a wave's
    first decision."""
    if self.per_env:
      return self._per_env(params, obs, t, active, prev)
    actions, sequences, infos = self.act(params, jnp.asarray(obs, jnp.float32), self.keys,
                                         t, prev, jnp.asarray(active), self.action_noise,
                                         self.intrinsic)
    kept = (np.asarray(self.sequence_of(sequences)) if self.sequence_of is not None
            else None)
    return np.asarray(actions), np.asarray(infos), kept, sequences if self.warm else prev

  def _per_env(self, params, obs, t, active, prev):
    prev = [None] * obs.shape[0] if prev is None else list(prev)
    actions = np.zeros((obs.shape[0], self.action_dim), np.float32)
    infos = np.tile(np.asarray(NO_PLAN_INFO, np.float32), (obs.shape[0], 1))
    kept = (np.zeros((obs.shape[0],) + self.sequence_shape, np.float32)
            if self.sequence_of is not None else None)
    for i in np.flatnonzero(active):
      action, sequence, info = self.act(params, np.asarray(obs[i], np.float32),
                                        self._sliced[i], t, prev[i], self.action_noise,
                                        self.intrinsic)
      if self.warm:
        prev[i] = sequence
      actions[i], infos[i] = np.asarray(action), np.asarray(info)
      if kept is not None:
        kept[i] = np.asarray(self.sequence_of(sequence))
    return actions, infos, kept, prev


def make_policy(settings: ActSettings, params, mode: str = 'plan', seed: int = 0
                ) -> Tuple[Callable[[np.ndarray], np.ndarray], Callable[..., None]]:
  """(policy, reset) for one episode at a time: policy(obs [obs_dim]) -> action [A].

  `reset(episode)` starts an episode: it forgets the previous sequence and sets the episode's
  key schedule from `episode.reset_seed` (module docstring; `reset()` without an episode keeps
  counting decisions under the last key). `policy.warmup(obs)` compiles it.
  """
  act = make_act(settings, mode)
  warm = uses_prev(settings.plan, mode)
  state = {'t': 0, 'prev': None, 'key': jax.random.key(seed)}

  def policy(obs: np.ndarray) -> np.ndarray:
    action, sequence, _ = act(params, jnp.asarray(obs, jnp.float32), state['key'], state['t'],
                              state['prev'])
    state['t'] += 1
    if warm:
      state['prev'] = sequence
    return np.asarray(action)

  def reset(episode=None) -> None:
    state['prev'] = None
    if episode is not None:
      state['key'] = episode_keys(seed, [episode.reset_seed])[0]
      state['t'] = 0

  policy.warmup = lambda obs: _compile_single(act, params, obs, state['key'], warm)
  return policy, reset
