"""One mesh of a participant: its vertices and its direct-access region."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from gymprecice.plugin.precice_xml import PreciceConfig


@dataclass
class Mesh:
    name: str
    dims: int
    provided: bool
    source: str | None = None  # participant a received mesh comes from
    api_access: bool = False
    chunks: list[np.ndarray] = field(default_factory=list)
    coords: np.ndarray | None = None
    region: np.ndarray | None = None

    @property
    def n(self) -> int:
        return len(self.coordinates)

    @property
    def coordinates(self) -> np.ndarray:
        if self.coords is None:
            self.coords = np.concatenate(self.chunks) if self.chunks else np.zeros((0, self.dims))
        return self.coords

    def add(self, positions: np.ndarray) -> np.ndarray:
        start = self.n
        self.chunks = [self.coordinates, positions.reshape(-1, self.dims).astype(np.float64)]
        self.coords = None
        return np.arange(start, start + len(positions), dtype=np.int32)

    def in_region(self) -> np.ndarray:
        """Indices of the vertices inside the access region (all without a region)."""
        coords = self.coordinates
        if self.region is None:
            return np.arange(len(coords))
        lo, hi = self.region[0::2], self.region[1::2]
        inside = np.all((coords >= lo) & (coords <= hi), axis=1)
        return np.nonzero(inside)[0]


def data_dims(cfg: PreciceConfig, data: str, mesh: str) -> int:
    """Components of ``data`` on ``mesh``: 1 for scalar data, the mesh's dimensions for vector data."""
    return 1 if cfg.data[data].kind == "scalar" else cfg.meshes[mesh].dimensions
