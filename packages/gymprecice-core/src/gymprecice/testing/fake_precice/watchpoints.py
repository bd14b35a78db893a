"""Watch points: the logs preCICE writes of the vertex nearest each point."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from gymprecice.plugin.precice_xml import ParticipantSpec, PreciceConfig
from gymprecice.testing.fake_precice.errors import PreciceError
from gymprecice.testing.fake_precice.mapping import nearest
from gymprecice.testing.fake_precice.mesh import Mesh, data_dims
from gymprecice.testing.fake_precice.store import Store


class WatchPoints:
    """The ``<watch-point>`` tags of one participant: checked, opened, and written per window.

    Each log is ``precice-<participant>-watchpoint-<name>.log`` in the working directory,
    with preCICE's header and one row (time, coordinates, every data of the mesh) per
    completed time window.
    """

    def __init__(self, name: str, cfg: PreciceConfig, spec: ParticipantSpec) -> None:
        self.name = name
        self.cfg = cfg
        self.spec = spec

    def _log(self, point: str) -> Path:
        return Path(f"precice-{self.name}-watchpoint-{point}.log")

    def check(self, meshes: dict[str, Mesh]) -> None:
        """preCICE allows watch points on provided meshes only."""
        for wp in self.spec.watch_points:
            mesh = meshes.get(wp.mesh)
            if mesh is None or not mesh.provided:
                raise PreciceError(
                    f'Participant "{self.name}" defines watchpoint "{wp.name}" for the received '
                    f'mesh "{wp.mesh}", which is not allowed. Please move the watchpoint '
                    f'definition to the participant providing mesh "{wp.mesh}".'
                )

    def open_logs(self) -> None:
        """Write each log's header (at construction, like preCICE)."""
        for wp in self.spec.watch_points:
            mesh = self.cfg.meshes[wp.mesh]
            columns = ["Time", *(f"Coordinate{i}" for i in range(mesh.dimensions))]
            for data in mesh.data:
                if self.cfg.data[data].kind == "scalar":
                    columns.append(data)
                else:
                    columns.extend(f"{data}{i}" for i in range(mesh.dimensions))
            header = "".join(f"  {c}" for c in columns)
            self._log(wp.name).write_text(header)

    def export(
        self, t: float, meshes: dict[str, Mesh], store: Store | None, degrees: dict[str, int]
    ) -> None:
        """Append one row per watch point: the nearest vertex's data sampled at ``t``."""
        for wp in self.spec.watch_points:
            mesh = meshes[wp.mesh]
            if mesh.n == 0:
                continue
            point = np.asarray(wp.coordinate, dtype=float)[: mesh.dims]
            vertex = int(nearest(point[None, :], mesh.coordinates)[0])
            values = [t, *mesh.coordinates[vertex]]
            for data in self.cfg.meshes[wp.mesh].data:
                dim = data_dims(self.cfg, data, wp.mesh)
                wave = store.wave((data, wp.mesh)) if store is not None else None
                if wave is not None and len(wave):
                    values.extend(wave.sample(t, degrees[data])[vertex][:dim])
                else:
                    values.extend([0.0] * dim)
            row = "\n" + "  ".join(f"{v:>15.8e}" for v in values)
            with open(self._log(wp.name), "a") as fh:
                fh.write(row)
