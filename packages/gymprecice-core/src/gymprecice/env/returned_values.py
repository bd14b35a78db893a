"""What a user's Adapter methods return, checked and found before anyone uses it.

Two things every Adapter (single- or multi-agent) does with the values a user's method
hands back, kept here so that both read them the same way:

* an observation or a reward with NaN or infinity never reaches a learner: it is refused
  with the method and the step named (:func:`refuse_non_finite`);
* the data ``_get_action`` produces for one coupling data field is found under its
  :class:`~gymprecice.core.DataRef`, its paper-style name ``"<data>-<interface>"``, or its
  interface's name where that interface writes one field only (:func:`find_written`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, Protocol

import numpy as np

__all__ = ["NonFiniteValueError", "WrittenRef", "find_written", "refuse_non_finite"]


class NonFiniteValueError(ValueError):
    """A user method returned NaN or infinity: a learner must never see it."""


class WrittenRef(Protocol):
    """What :func:`find_written` reads of a data reference (a ``DataRef`` is one)."""

    @property
    def interface(self) -> str: ...


def refuse_non_finite(value: Any, method: str, env_index: int, step: int) -> None:
    """Raise when ``value`` (an observation, a dict of them, or a reward) is not finite."""
    items = value.items() if isinstance(value, Mapping) else [("", value)]
    for key, part in items:
        try:
            array = np.asarray(part, dtype=float)
        except (TypeError, ValueError):
            continue  # not numeric (a Discrete space's int is fine; text is not ours)
        if not np.all(np.isfinite(array)):
            where = f"[{key!r}]" if key else ""
            raise NonFiniteValueError(
                f"env {env_index}: {method}() returned a non-finite value{where} (NaN or "
                f"infinity) at step {step}: {array.tolist() if array.size <= 8 else array}; "
                "it was not passed to the learner. Check the solver output it reads (a "
                "diverging solver belongs in its plugin's gymprecice_detect_divergence)"
            )


def find_written(produced: Mapping[Any, Any], ref: WrittenRef, refs: Sequence[WrittenRef]) -> Any:
    """Find ``ref``'s values under its DataRef, its paper-style name, or its interface
    (``refs``: every data field written, to tell whether the interface has one only);
    ``None`` when ``produced`` has none of them."""
    for key in (ref, str(ref)):
        if key in produced:
            return produced[key]
    if ref.interface in produced and sum(r.interface == ref.interface for r in refs) == 1:
        return produced[ref.interface]
    return None
