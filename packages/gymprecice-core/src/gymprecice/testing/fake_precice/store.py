"""The data a participant exchanges: its flows and every waveform, keyed by (data, mesh)."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np

from gymprecice.testing.fake_precice.waveform import Waveform

Key = tuple[str, str]  # (data name, mesh name)


@dataclass
class Flow:
    """One exchanged data of a coupling scheme, from this participant's point of view."""

    data: str
    mesh: str
    partner: str
    initialize: bool
    substeps: bool

    @property
    def key(self) -> Key:
        return (self.data, self.mesh)


class Store:
    """Every waveform of one participant, keyed by (data, mesh), and what moves them."""

    def __init__(self, degrees: dict[str, int]) -> None:
        self.waves: dict[Key, Waveform] = {}
        self.degrees = degrees

    def wave(self, key: Key) -> Waveform:
        return self.waves.setdefault(key, Waveform())

    def payload(self, flows: Iterable[Flow]) -> tuple[list[Any], list[np.ndarray]]:
        entries: list[Any] = []
        arrays: list[np.ndarray] = []
        for flow in flows:
            wave = self.wave(flow.key)
            if flow.substeps:
                entries.append([flow.data, flow.mesh, list(wave.times)])
                arrays.extend(wave.values)
            else:
                entries.append([flow.data, flow.mesh, None])
                arrays.append(wave.last())
        return entries, arrays

    def deliver(
        self, flows: Iterable[Flow], entries: list[Any], arrays: list[np.ndarray], at: float
    ) -> None:
        received: dict[Key, tuple[list[float] | None, list[np.ndarray]]] = {}
        pos = 0
        for data, mesh, times in entries:
            count = 1 if times is None else len(times)
            received[(data, mesh)] = (times, arrays[pos : pos + count])
            pos += count
        for flow in flows:
            times, values = received[flow.key]
            wave = self.wave(flow.key)
            if times is None:
                wave.set(at, values[0])
            else:
                if times:
                    wave.trim_after(times[0])
                for t, v in zip(times, values):
                    wave.set(t, v)

    def zero_at(self, flows: Iterable[Flow], t: float, shapes: dict[Key, tuple[int, int]]) -> None:
        for flow in flows:
            self.wave(flow.key).set(t, np.zeros(shapes[flow.key]))

    def move(self, keys: Iterable[Key]) -> None:
        for key in keys:
            self.wave(key).move()
