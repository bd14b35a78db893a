"""Nearest-neighbour mapping between meshes, and the mappings of one participant."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from gymprecice.plugin.precice_xml import MappingSpec, ParticipantSpec, PreciceConfig
from gymprecice.testing.fake_precice.errors import PreciceError
from gymprecice.testing.fake_precice.mesh import Mesh
from gymprecice.testing.fake_precice.numerics import greater
from gymprecice.testing.fake_precice.store import Key, Store
from gymprecice.testing.fake_precice.waveform import Waveform


def nearest(query: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """Index of the nearest reference vertex for every query vertex (chunked brute force)."""
    index = np.zeros(len(query), dtype=np.int64)
    if len(reference) == 0 or len(query) == 0:
        return index
    chunk = max(1, 4_000_000 // max(1, len(reference)))
    for lo in range(0, len(query), chunk):
        part = query[lo : lo + chunk]
        d2 = ((part[:, None, :] - reference[None, :, :]) ** 2).sum(axis=2)
        index[lo : lo + chunk] = d2.argmin(axis=1)
    return index


class Mapping:
    """A nearest-neighbour mapping between two meshes, computed once at ``initialize``."""

    def __init__(self, spec: MappingSpec, source: np.ndarray, target: np.ndarray) -> None:
        self.spec = spec
        self.consistent = spec.constraint != "conservative"
        self.n_source = len(source)
        self.n_target = len(target)
        if self.consistent:
            self.index = nearest(target, source)
        else:
            self.index = nearest(source, target)

    def apply(self, values: np.ndarray) -> np.ndarray:
        dim = values.shape[1]
        if self.consistent:
            if self.n_source == 0:
                return np.zeros((self.n_target, dim))
            return values[self.index]
        out = np.zeros((self.n_target, dim))
        if self.n_target:
            np.add.at(out, self.index, values)
        return out


class Mappings:
    """One participant's mappings, built at ``initialize`` once the received meshes are in.

    A read mapping fills the read mesh's waveform from the received one after every
    exchange; a write mapping fills the sent mesh's waveform from the written one before
    it. Every method other than ``nearest-neighbor`` runs as nearest-neighbor (logged).
    """

    def __init__(
        self,
        name: str,
        cfg: PreciceConfig,
        spec: ParticipantSpec,
        meshes: dict[str, Mesh],
        reads: set[Key],
        writes: set[Key],
        log: Callable[[str], None],
    ) -> None:
        self.read: list[tuple[Mapping, str]] = []
        self.write: list[tuple[Mapping, str]] = []
        for mapping_spec in spec.mappings:
            source = meshes.get(mapping_spec.from_mesh)
            target = meshes.get(mapping_spec.to_mesh)
            if source is None or target is None:
                missing = mapping_spec.from_mesh if source is None else mapping_spec.to_mesh
                raise PreciceError(
                    f'Participant "{name}" defines a mapping with mesh "{missing}", which it '
                    "neither provides nor receives."
                )
            if mapping_spec.method != "nearest-neighbor":
                log(
                    f'fake_precice runs mapping "{mapping_spec.method}" from '
                    f'"{mapping_spec.from_mesh}" to "{mapping_spec.to_mesh}" as nearest-neighbor'
                )
            mapping = Mapping(mapping_spec, source.coordinates, target.coordinates)
            shared = [
                d
                for d in cfg.meshes[mapping_spec.from_mesh].data
                if d in cfg.meshes[mapping_spec.to_mesh].data
            ]
            if mapping_spec.direction == "read":
                for data in shared:
                    if (data, mapping_spec.to_mesh) in reads:
                        self.read.append((mapping, data))
            else:
                for data in shared:
                    if (data, mapping_spec.from_mesh) in writes:
                        self.write.append((mapping, data))

    def map_written(self, store: Store, after: float | None) -> None:
        """Map the written samples later than ``after`` (all of them where it is None)."""
        for mapping, data in self.write:
            source = store.wave((data, mapping.spec.from_mesh))
            target = store.wave((data, mapping.spec.to_mesh))
            if after is not None:
                target.trim_after(after)
            for t, v in zip(source.times, source.values):
                if after is None or greater(t, after):
                    target.set(t, mapping.apply(v))

    def map_read(self, store: Store) -> None:
        """Replace each read mesh's waveform by the mapped received one."""
        for mapping, data in self.read:
            source = store.wave((data, mapping.spec.from_mesh))
            target = Waveform()
            for t, v in zip(source.times, source.values):
                target.set(t, mapping.apply(v))
            store.waves[(data, mapping.spec.to_mesh)] = target
