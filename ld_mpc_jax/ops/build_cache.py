"""One built function per distinct value of frozen settings, so that building it again traces
nothing.

`jax.jit` caches its traces per function object. A builder such as `build_plan(model, plan)`
makes a new closure at every call, so a second run of the same settings in one process would
trace and lower the whole program again (about 20 s of the 28 s of a smoke training run on a
2-core CPU, measured with the compiled program already in the persistent cache).
`by_settings` keys the built function on its arguments, which are frozen and hashable
(ld_mpc_jax.model.settings), and on the registries' generation: a kind registered or removed
since invalidates every entry.
"""

import collections
import functools
from typing import Callable

from ld_mpc_jax.ops import registry

MAX_ENTRIES = 8  # Per builder; the least recently used entry goes first.


def by_settings(build: Callable) -> Callable:
  """Wraps build(*settings) -> fn: returns the same fn for equal settings while no registry
  changes."""
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
