"""Named kinds, one registry per family (proposal, dynamics, value, actor, candidate kind, data
source, policy mode, environment suite).

A kind is one module and one entry:

  DYNAMICS = Registry('dynamics', 'config.model.dynamics_type')

  @DYNAMICS.register('mlp')
  class MLPDynamics: ...

  DYNAMICS.get(config.model.dynamics_type)   # ValueError naming the registered kinds if unknown

Config checks read the registries (`Registry.check`), so a name is typed once, where its kind is
defined. Lookups never fall back to a default: an unknown name is a one-line error.
"""

from typing import Any, Callable, Dict, Iterator, Tuple

_generation = [0]  # Bumped whenever any registry changes (build_cache keys on it).


def generation() -> int:
  """How many times any registry has changed in this process."""
  return _generation[0]


class Registry:
  """Name -> entry for one family of kinds, in registration order."""

  def __init__(self, family: str, field: str = ''):
    self.family = family
    self.field = field or family  # How the config names it, for error messages.
    self._entries: Dict[str, Any] = {}

  def register(self, name: str, entry: Any = None) -> Callable:
    """Registers `entry` under `name` (or, as a decorator, the decorated object); returns it.
    Registering a name twice is an error (one kind, one entry)."""
    def add(obj):
      if name in self._entries:
        raise ValueError(f'{self.family} kind {name!r} is already registered')
      self._entries[name] = obj
      _generation[0] += 1
      return obj
    return add if entry is None else add(entry)

  def unregister(self, name: str) -> None:
    """Removes `name` (tests that register a toy kind clean up after themselves)."""
    self._entries.pop(name)
    _generation[0] += 1

  def check(self, name: str) -> str:
    """`name` if it is registered, else a one-line ValueError listing the registered names."""
    if name not in self._entries:
      raise ValueError(f'{self.field} must be one of {", ".join(map(repr, self.names()))}, '
                       f'got {name!r}')
    return name

  def get(self, name: str) -> Any:
    return self._entries[self.check(name)]

  def names(self) -> Tuple[str, ...]:
    return tuple(self._entries)

  def index(self, name: str) -> int:
    """Position of `name` in registration order (stable ids, e.g. in plan outputs)."""
    return self.names().index(self.check(name))

  def __contains__(self, name: str) -> bool:
    return name in self._entries

  def __iter__(self) -> Iterator[str]:
    return iter(self._entries)

  def __len__(self) -> int:
    return len(self._entries)
