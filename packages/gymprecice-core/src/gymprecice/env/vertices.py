"""The controller's vertices on every coupling interface, and where each comes from.

In order of precedence: the env's own (``set_interface_vertices``), preCICE's for a
direct-access mesh (known after the coupling is initialized), or the plugin of the
partner solver (``gymprecice_interface_geometry``, which reads the solver's prepared case).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from gymprecice.env.config import GymPreciceConfig, InterfaceSpec
from gymprecice.env.coupled_run import CoupledRun
from gymprecice.plugin.errors import ConfigError
from gymprecice.plugin.solver import InterfaceGeometry

__all__ = ["ControllerVertices", "fit_dimensions"]


class ControllerVertices:
    """The geometry of every interface of one env, found once and kept until it changes."""

    def __init__(self, config: GymPreciceConfig, run: CoupledRun) -> None:
        self._config = config
        self._run = run
        self._user: dict[str, np.ndarray] = {}
        self._direct: dict[str, InterfaceGeometry] = {}
        self._found: dict[str, InterfaceGeometry] | None = None

    def set(self, interface: str, coordinates: Any) -> None:
        """The env's own vertices of ``interface`` (they override every plugin's)."""
        if interface not in self._config.interfaces:
            raise ConfigError(
                f"{self._config.where()}: no interface {interface!r}; the interfaces are "
                f"{sorted(self._config.interfaces)}"
            )
        coords = np.atleast_2d(np.asarray(coordinates, dtype=float))
        dims = self._config.interfaces[interface].dimensions
        if coords.shape[1] != dims:
            raise ValueError(
                f"interface {interface!r}: coordinates have {coords.shape[1]} columns but mesh "
                f"{self._config.interfaces[interface].mesh!r} is {dims}-D"
            )
        self._user[interface] = coords
        self._found = None

    def known(self) -> dict[str, InterfaceGeometry]:
        """Every interface's geometry, but a direct-access one's before it is known."""
        if self._found is None:
            self._found = {
                name: self._find(spec)
                for name, spec in self._config.interfaces.items()
                if not spec.direct or name in self._direct or name in self._user
            }
        return self._found

    def set_direct(self, coordinates: Mapping[str, Any]) -> None:
        """preCICE's vertices of the direct-access meshes (``{mesh: coordinates}``)."""
        if not coordinates:
            return
        for spec in self._config.interfaces.values():
            if spec.mesh in coordinates:
                self._direct[spec.name] = InterfaceGeometry(np.asarray(coordinates[spec.mesh]))
        self._found = None

    def access_region(self, spec: InterfaceSpec) -> list[float]:
        """Bounding box of a direct-access mesh: the user's, or all of space."""
        region = self._config.controller.access_regions.get(spec.name)
        if region is not None:
            return list(region)
        return [-1e300, 1e300] * spec.dimensions

    def _find(self, spec: InterfaceSpec) -> InterfaceGeometry:
        if spec.name in self._user:
            return InterfaceGeometry(self._user[spec.name])
        if spec.direct:
            if spec.name in self._direct:
                return self._direct[spec.name]
            raise ConfigError(
                f"interface {spec.name!r} reads mesh {spec.mesh!r} through direct access: "
                f"its vertices are defined by {spec.partner!r} and known after reset()"
            )
        self._run.prepare()
        for solver in self._run.solvers.values():
            if spec.partner and solver.participant and solver.participant != spec.partner:
                continue
            geometry = self._run.hook.gymprecice_interface_geometry(
                solver=solver, interface=spec.name, mesh=spec.partner_mesh or spec.mesh
            )
            if geometry is not None:
                return fit_dimensions(geometry, spec.dimensions)
        raise ConfigError(
            f"{self._config.where()}: no plugin knows the vertices of interface {spec.name!r} "
            f"(mesh {spec.mesh!r}, coupled to {spec.partner or 'no participant'}'s mesh "
            f"{spec.partner_mesh!r}); call self.set_interface_vertices({spec.name!r}, coords) "
            "in your env's __init__"
        )


def fit_dimensions(geometry: InterfaceGeometry, dimensions: int) -> InterfaceGeometry:
    """preCICE 2-D meshes take (x, y): drop z from 3-D coordinates of a 2-D case."""
    coords = geometry.coordinates
    if coords.shape[1] == dimensions:
        return geometry
    if coords.shape[1] == 3 and dimensions == 2:
        return InterfaceGeometry(coords[:, :2], geometry.normals, geometry.areas, geometry.patches)
    raise ValueError(
        f"interface coordinates have {coords.shape[1]} columns but the preCICE mesh is {dimensions}-D"
    )
