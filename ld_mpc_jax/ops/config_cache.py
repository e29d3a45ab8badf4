"""One built function per distinct config or settings, so that building it again traces nothing.

`jax.jit` caches its traces per function object. A builder such as `make_update(config)` makes a
new closure at every call, so a second run of the same config in one process traces and lowers
the whole update step again (about 20 s of the 28 s of a smoke training run on a 2-core CPU,
measured with the compiled program already in the persistent cache). `by_config` keys the built
function on the config's value (its JSON) and on the registries' generation (a kind registered
or removed since invalidates every entry), and builds it from a deep copy of the config, so that
a caller changing its config afterwards changes nothing.
"""

import collections
import copy
import functools
from typing import Callable

import ml_collections

from ld_mpc_jax.ops import registry

MAX_ENTRIES = 8  # Per builder; the least recently used entry goes first.


def config_key(config: ml_collections.ConfigDict) -> str:
  """The config's value as a string: equal configs, equal keys, whatever their field order."""
  return config.to_json_best_effort(sort_keys=True)


def by_config(build: Callable) -> Callable:
  """Wraps build(config) -> fn: returns the same fn for every config of the same value."""
  entries = collections.OrderedDict()

  @functools.wraps(build)
  def cached(config: ml_collections.ConfigDict):
    key = (registry.generation(), config_key(config))
    if key in entries:
      entries.move_to_end(key)
      return entries[key]
    fn = build(copy.deepcopy(config))
    entries[key] = fn
    while len(entries) > MAX_ENTRIES:
      entries.popitem(last=False)
    return fn

  cached.cache_size = lambda: len(entries)
  return cached


def by_settings(build: Callable) -> Callable:
  """Wraps build(*settings) -> fn, its arguments frozen and hashable (ld_mpc_jax.model.settings):
  returns the same fn for equal arguments while no registry changes."""
  entries = collections.OrderedDict()

  @functools.wraps(build)
  def cached(*settings):
    key = (registry.generation(),) + settings
    if key in entries:
      entries.move_to_end(key)
      return entries[key]
    fn = build(*settings)
    entries[key] = fn
    while len(entries) > MAX_ENTRIES:
      entries.popitem(last=False)
    return fn

  cached.cache_size = lambda: len(entries)
  return cached
