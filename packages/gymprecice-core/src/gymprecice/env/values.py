"""The value types an Adapter hands to its user's methods and puts in ``info``.

* :class:`DataRef`: one piece of coupling data, the entries of ``write_var_list`` and
  ``read_var_list``;
* :class:`DataDict`: the coupling data read in one step, keyed by :class:`DataRef` and
  reachable by the Gym-preCICE paper's names too;
* :class:`Timing`: ``info["timing"]``, the seconds of one step or reset.

They are importable from :mod:`gymprecice.core` as well, where an env's author meets them.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, NamedTuple

__all__ = ["DataDict", "DataRef", "Timing"]


class DataRef(NamedTuple):
    """One piece of coupling data: ``data`` on the controller mesh of ``interface``.

    ``str(ref)`` is ``"<data>-<interface>"``, the key the Gym-preCICE paper used.
    """

    interface: str
    mesh: str
    data: str

    def __str__(self) -> str:
        return f"{self.data}-{self.interface}"


class DataDict(dict):
    """Coupling data keyed by :class:`DataRef`, also reachable by ``"Data-interface"``.

    An interface with a single data field can be looked up by its interface name too.
    """

    def __getitem__(self, key: Any) -> Any:
        if isinstance(key, DataRef) or not isinstance(key, str):
            return super().__getitem__(key)
        for ref in self:
            if str(ref) == key:
                return super().__getitem__(ref)
        matches = [ref for ref in self if ref.interface == key]
        if len(matches) == 1:
            return super().__getitem__(matches[0])
        raise KeyError(key)


class Timing(Mapping[str, float]):
    """Seconds spent in one step or reset: ``precice_s``, ``wait_s``, ``env_s``, ``step_s``.

    ``wait_s`` is the time spent waiting for the solvers: in preCICE, in the
    ``wait_until`` of readers from :meth:`~gymprecice.core.Adapter.open_output`, and on an
    episode's last step in finalizing and letting the solvers exit; ``env_s`` the rest of
    the env's own code, so ``wait_s + env_s`` accounts for ``step_s`` but for a few
    bookkeeping lines. Read it like a dict. Two timings compare equal when they measure the
    same things: wall-clock figures describe the machine, not the environment's state, so
    Gymnasium's determinism check (which compares the infos of two identical steps) must
    not see them.
    """

    __slots__ = ("_seconds",)

    def __init__(self, seconds: Mapping[str, float]) -> None:
        self._seconds = dict(seconds)

    def __getitem__(self, key: str) -> float:
        return self._seconds[key]

    def __iter__(self):
        return iter(self._seconds)

    def __len__(self) -> int:
        return len(self._seconds)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Timing) and self._seconds.keys() == other._seconds.keys()

    __hash__ = None  # type: ignore[assignment]

    def __repr__(self) -> str:
        return f"Timing({self._seconds!r})"

    def __reduce__(self):
        return (Timing, (self._seconds,))
