"""What an online run learns with (`Learner`): every training seed's TrainState stacked on a seed
axis, the jitted update, and the counters of the updates made. A wave asks it to catch up with
the environment steps taken (`catch_up`); nothing else in the online loop changes the states."""

from typing import Dict, List, Sequence

import jax
import jax.numpy as jnp
import numpy as np

from ld_mpc_jax.learn.train_state import make_seeds_update, stack_states
from ld_mpc_jax.model.models import set_obs_normalization
from ld_mpc_jax.ops.seed_groups import SeedGroups

COUNTERS = ('updates', 'pretrain_updates', 'normalized')  # The learner's, in the buffer files.


class Learner:
  """The training seeds' TrainStates, in one stack per device (`train.seed_devices` groups,
  `ops.seed_groups`), updated by the update vmapped over each group's seeds
  (`train_state.make_seeds_update`), so each seed's run is the one it would make alone."""

  def __init__(self, learn, online, batch_size: int, seed_devices: int, states: Sequence,
               buffers: Sequence, update_keys: Sequence, counters: Dict):
    """`learn`: the seeds' LearnSettings; `online`: their OnlineSettings (the update ratio,
    updates per call, demonstrations); `states`: each seed's TrainState; `buffers`: each seed's
    online Buffer (sampled for the updates); `update_keys`: each seed's update key; `counters`:
    updates and pretrain_updates made so far, and 'normalized' (False: the observation
    statistics are still to be set from the seed episodes)."""
    self.model, self.online, self.batch_size = learn.model, online, batch_size
    self.buffers = list(buffers)
    self.counters = {k: counters[k] for k in COUNTERS if k in counters}
    self.groups = SeedGroups(len(self.buffers), seed_devices)
    self.states = self.groups.split(stack_states(list(states)))  # One stack per device.
    self.per_call = online.updates_per_call
    self.update = {n: make_seeds_update(learn, n, self.per_call) for n in set(self.groups.sizes)}
    self.keys = self.groups.split(jnp.stack(list(update_keys)))
    # Each seed's update key at an update count: one jitted call, not one per seed.
    self._fold = jax.jit(jax.vmap(jax.random.fold_in, in_axes=(0, None)))
    self.metrics: List = []
    self._views = None

  def views(self) -> list:
    """Each seed's EMA parameters (one jitted slicing per change of the states)."""
    if self._views is None:
      self._views = self.groups.per_seed([g.ema_params for g in self.states])
    return self._views

  def group_ema_params(self) -> list:
    """Each device's stacked EMA parameters (the acting policy's, `WavePolicy`)."""
    return [g.ema_params for g in self.states]

  def per_seed_states(self) -> list:
    return self.groups.per_seed(self.states)

  def seed_metrics(self) -> Dict[str, np.ndarray]:
    """The last update's metrics, [num_seeds] numpy per name ({} before the first update)."""
    return self.groups.join_host(self.metrics) if self.metrics else {}

  def catch_up(self, env_steps: int) -> None:
    """Updates until floor(update_ratio x `env_steps`) have been made.

    `env_steps` may count steps the environments are about to take: the updates they call for
    are dispatched before the environments step, so that XLA computes them (asynchronously, on
    its own threads) while MuJoCo steps: the same updates in the same order as when they wait
    for the steps (the buffers change only between waves), the environment loop off the
    critical path.

    From scratch, the first call sets the encoder's observation statistics from the seed
    episodes and demonstrations (`config.model.normalize_obs`) before any update, then makes
    the `online.demo_pretrain_updates` updates on the demonstrations alone (MoDem's BC
    pretraining; not counted in the update ratio).
    """
    c, o = self.counters, self.online
    if not c.get('normalized', True):  # Fine-tuning starts normalized (no key).
      self._normalize()
    if o.demos and c['pretrain_updates'] < o.demo_pretrain_updates:
      self._updates(o.demo_pretrain_updates, 'pretrain_updates', share=1.0)
    self._updates(int(o.update_ratio * env_steps), 'updates', share=o.demo_share(env_steps))

  def _normalize(self) -> None:
    params = stack_states([set_obs_normalization(
        p, np.concatenate([ep['obs'] for ep in b.episodes + b.demos]),
        self.model.obs_mask_constant)
                           for b, p in zip(self.buffers, self.groups.per_seed(
                               [g.params for g in self.states]))])
    self.states = [state.replace(  # Copies: the update donates both trees.
        params=p, ema_params=jax.tree_util.tree_map(jnp.copy, p))
                   for state, p in zip(self.states, self.groups.split(params))]
    self.counters['normalized'], self._views = True, None

  def _updates(self, target: int, counter: str, share: float) -> None:
    """Updates until counters[counter] reaches `target`, `online.updates_per_call` per jitted
    call, a `share` of each batch from the demonstrations (`Buffer.sample`)."""
    c, batch, n = self.counters, self.batch_size, self.per_call
    while c[counter] + n <= target:
      per_seat = [b.sample(batch, n, share) for b in self.buffers]
      shape = (n, batch) if n > 1 else (batch,)
      windows = {k: np.stack([w[k].reshape(shape + w[k].shape[1:]) for w in per_seat])
                 for k in per_seat[0]}
      step = c['updates'] + c['pretrain_updates']  # One key per update made.
      # One call per device, dispatched without waiting: the devices update at the same time.
      out = [self.update[g](state, part, self._fold(keys, step)) for g, state, part, keys in
             zip(self.groups.sizes, self.states, self.groups.split_host(windows), self.keys)]
      self.states, self.metrics = [o[0] for o in out], [o[1] for o in out]
      c[counter] += n
      self._views = None
