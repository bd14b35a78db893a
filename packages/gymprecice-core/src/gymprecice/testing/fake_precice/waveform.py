"""The time samples of one data on one mesh, and their interpolation in time."""

from __future__ import annotations

import numpy as np

from gymprecice.testing.fake_precice.numerics import equals, greater, greater_equals, smaller


class Waveform:
    """Time samples of one data on one mesh: what ``read_data`` interpolates in time."""

    __slots__ = ("times", "values")

    def __init__(self) -> None:
        self.times: list[float] = []
        self.values: list[np.ndarray] = []

    def __len__(self) -> int:
        return len(self.times)

    def set(self, t: float, values: np.ndarray) -> None:
        for i, ti in enumerate(self.times):
            if equals(ti, t):
                self.values[i] = values
                return
            if ti > t:
                self.times.insert(i, t)
                self.values.insert(i, values)
                return
        self.times.append(t)
        self.values.append(values)

    def last(self) -> np.ndarray:
        return self.values[-1]

    def move(self) -> None:
        if len(self.times) > 1:
            self.times = self.times[-1:]
            self.values = self.values[-1:]

    def trim_before(self, t: float) -> None:
        keep = [i for i, ti in enumerate(self.times) if not smaller(ti, t)]
        self.times = [self.times[i] for i in keep]
        self.values = [self.values[i] for i in keep]

    def trim_after(self, t: float) -> None:
        keep = [i for i, ti in enumerate(self.times) if not greater(ti, t)]
        self.times = [self.times[i] for i in keep]
        self.values = [self.values[i] for i in keep]

    def sample(self, t: float, degree: int) -> np.ndarray:
        n = len(self.times)
        if min(degree, n - 1) == 0:
            if n == 1:
                return self.values[0]
            for ti, vi in zip(self.times, self.values):
                if greater_equals(ti, t):
                    return vi
            return self.values[-1]
        for i, ti in enumerate(self.times):
            if equals(ti, t):
                return self.values[i]
            if ti > t:
                if i == 0:
                    return self.values[0]
                t0 = self.times[i - 1]
                w = (t - t0) / (ti - t0)
                return (1.0 - w) * self.values[i - 1] + w * self.values[i]
        return self.values[-1]
