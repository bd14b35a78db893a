"""A solver output reader whose waits count as waiting for the solver, and are watched.

:meth:`gymprecice.core.Adapter.open_output` hands out the plugin's reader wrapped in a
:class:`TimedReader`.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from gymprecice.plugin.solver import OutputReader

__all__ = ["OUTPUT_WAIT_SLICE_S", "TimedReader"]

#: seconds between two looks at the solvers while an env waits for a solver's output file
OUTPUT_WAIT_SLICE_S = 0.5


class TimedReader:
    """A solver output reader whose ``wait_until`` calls are timed and watched.

    Waiting for a solver's output files is waiting for the solver, as much as waiting in
    preCICE is; timing it lets ``info["timing"]`` count it as such instead of as env code
    (an env that waits for a watch point would otherwise look 98 % busy in Python).
    It is also watched like a wait in preCICE: the wait runs in slices of
    :data:`OUTPUT_WAIT_SLICE_S`, and between two slices ``alive()`` raises if a solver has
    died, so a crashed or diverged solver ends the step at once instead of after the
    reader's whole timeout. Everything else goes straight to the plugin's reader.
    ``clock[0]`` accumulates the seconds waited.
    """

    def __init__(
        self, reader: OutputReader, clock: list[float], alive: Callable[[], None] | None = None
    ) -> None:
        self._reader = reader
        self._clock = clock
        self._alive = alive

    def wait_until(self, time_: float, timeout: float, *args: Any, **kwargs: Any) -> Any:
        wait = getattr(self._reader, "wait_until", None)
        if wait is None:
            raise AttributeError(
                f"{type(self._reader).__name__} has no wait_until: the plugin's reader does not "
                "follow gymprecice.solver.WaitableOutputReader; poll read_new() instead"
            )
        started = time.perf_counter()
        try:
            if self._alive is None:
                return wait(time_, timeout, *args, **kwargs)
            deadline = time.monotonic() + max(0.0, timeout)
            while True:
                left = deadline - time.monotonic()
                try:
                    return wait(time_, min(left, OUTPUT_WAIT_SLICE_S), *args, **kwargs)
                except TimeoutError as exc:
                    if left <= OUTPUT_WAIT_SLICE_S:  # the reader's own error, its last slice
                        exc.add_note(f"(waited {timeout:g} s in all, every solver running)")
                        raise
                    self._alive()
        finally:
            self._clock[0] += time.perf_counter() - started

    def __getattr__(self, name: str) -> Any:
        if name in ("_reader", "_clock", "_alive"):  # not set yet (copy, unpickling)
            raise AttributeError(name)
        return getattr(self._reader, name)
