"""preCICE's time keeping: a compensated sum and a window start plus progress."""

from __future__ import annotations

import math

from gymprecice.testing.fake_precice.numerics import equals


class Kahan:
    """Compensated sum, as preCICE keeps its time: many small steps add up exactly enough."""

    __slots__ = ("comp", "total")

    def __init__(self, total: float = 0.0, comp: float = 0.0) -> None:
        self.total = total
        self.comp = comp

    def add(self, value: float) -> None:
        y = value - self.comp
        t = self.total + y
        self.comp = (t - self.total) - y
        self.total = t

    def plus(self, value: float) -> float:
        other = Kahan(self.total, self.comp)
        other.add(value)
        return other.total


class Time:
    """Window start plus progress inside the window, with an optional end time."""

    __slots__ = ("max_time", "progress", "start")

    def __init__(self, max_time: float | None) -> None:
        self.max_time = max_time
        self.start = Kahan()
        self.progress = Kahan()

    def reset_to(self, t: float) -> None:
        self.start = Kahan(t)
        self.progress = Kahan()

    def progress_by(self, dt: float) -> None:
        self.progress.add(dt)

    def reset_progress(self) -> None:
        self.progress = Kahan()

    def complete_window(self, size: float) -> None:
        if equals(self.progress.total, size):
            self.start.add(size)
        else:  # the truncated last window, when max-time is not a multiple of the size
            self.start.add(self.progress.total)
        self.reset_progress()

    def time(self) -> float:
        return self.start.plus(self.progress.total)

    def until_time(self, t: float) -> float:
        return -(self.time() - t)

    def until_end(self) -> float:
        return math.inf if self.max_time is None else self.until_time(self.max_time)

    def until_window_end(self, size: float) -> float:
        until = -Kahan(self.progress.total, self.progress.comp).plus(-size)
        return min(until, self.until_end())

    def reached_end(self) -> bool:
        return self.max_time is not None and equals(self.until_time(self.max_time), 0.0)

    def reached_end_of_window(self, size: float) -> bool:
        return equals(self.until_window_end(size), 0.0)
