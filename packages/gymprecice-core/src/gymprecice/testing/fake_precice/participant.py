"""The double's ``Participant``: pyprecice v3's API, its protocol checks and messages."""

from __future__ import annotations

import contextlib
import functools
import hashlib
import math
import sys
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

from gymprecice.plugin.errors import ConfigError
from gymprecice.plugin.precice_xml import PreciceConfig, load_precice_config
from gymprecice.testing.fake_precice.arguments import as_vertex_ids, check_array_like, convert
from gymprecice.testing.fake_precice.config_extras import read_extras, truthy
from gymprecice.testing.fake_precice.coupling import Coupling
from gymprecice.testing.fake_precice.errors import PreciceError, fatal
from gymprecice.testing.fake_precice.mapping import Mappings
from gymprecice.testing.fake_precice.mesh import Mesh, data_dims
from gymprecice.testing.fake_precice.numerics import NUMERICAL_ZERO, equals
from gymprecice.testing.fake_precice.rendezvous import Rendezvous
from gymprecice.testing.fake_precice.schemes import build_schemes
from gymprecice.testing.fake_precice.schemes.base import (
    INITIALIZE_DATA,
    READ_CHECKPOINT,
    WRITE_CHECKPOINT,
)
from gymprecice.testing.fake_precice.spelling import best_match
from gymprecice.testing.fake_precice.store import Key
from gymprecice.testing.fake_precice.version import PRECICE_VERSION
from gymprecice.testing.fake_precice.watchpoints import WatchPoints

#: Mappings that need edges/triangles of one mesh (requires_mesh_connectivity_for).
CONNECTIVITY_METHODS = ("nearest-projection", "linear-cell-interpolation")


class Participant:
    """Drop-in for ``precice.Participant`` (pyprecice v3); see :mod:`gymprecice.testing.fake_precice`.

    One object is one participant of one coupled run. It is not thread-safe, and like the
    real library it is meant to live in its own process.
    """

    def __init__(
        self,
        participant_name: str,
        configuration_file_name: str,
        solver_process_index: int,
        solver_process_size: int,
        communicator: Any = None,
    ) -> None:
        self._state = "constructed"
        self._coupling: Coupling | None = None
        self._name = convert(participant_name)
        config_file = convert(configuration_file_name)
        if not self._name:
            raise PreciceError(
                "This participant's name is an empty string. When constructing a preCICE "
                "interface you need to pass the name of the participant as first argument to "
                "the constructor."
            )
        rank, size = int(solver_process_index), int(solver_process_size)
        if rank < 0:
            raise PreciceError(
                f"The solver process index needs to be a non-negative number, not: {rank}. "
                "Please check the value given when constructing a preCICE interface."
            )
        if size < 1:
            raise PreciceError(
                f"The solver process size needs to be a positive number, not: {size}. "
                "Please check the value given when constructing a preCICE interface."
            )
        if rank >= size:
            raise PreciceError(
                f"The solver process index, currently: {rank}  needs to be smaller than the "
                f"solver process size, currently: {size}. Please check the values given when "
                "constructing a preCICE interface."
            )
        if size > 1:
            raise PreciceError(
                "gymprecice's fake_precice runs serial participants only "
                f"(solver_process_size={size}); use real preCICE for parallel participants."
            )
        self._config_path = Path(config_file)
        try:
            self._cfg: PreciceConfig = load_precice_config(self._config_path)
            root_attrs, self._log_enabled, extras = read_extras(self._config_path)
            self._config_hash = hashlib.sha256(self._config_path.read_bytes()).hexdigest()
        except ConfigError as exc:
            raise PreciceError(str(exc)) from exc
        self._experimental = truthy(root_attrs.get("experimental"))
        self._allow_remeshing = truthy(root_attrs.get("allow-remeshing"))
        self._log(f"This is preCICE version {PRECICE_VERSION} (gymprecice fake_precice)")
        self._log(f'Configuring preCICE with configuration "{config_file}"')
        self._log(f'I am participant "{self._name}"')
        if len(self._cfg.participants) < 2:
            raise PreciceError(
                "In the preCICE configuration, only one participant is defined. One participant "
                "makes no coupled simulation. Please add at least another one."
            )
        if self._name not in self._cfg.participants:
            raise PreciceError(
                "This participant's name, which was specified in the constructor of the preCICE "
                f'interface as "{self._name}", is not defined in the preCICE configuration. '
                "Please double-check the correct spelling."
            )
        self._spec = self._cfg.participants[self._name]
        self._degrees = {
            name: (1 if d.waveform_degree is None else d.waveform_degree)
            for name, d in self._cfg.data.items()
        }
        self._meshes: dict[str, Mesh] = {}
        for name in self._spec.provided_meshes:
            self._meshes[name] = Mesh(name, self._cfg.meshes[name].dimensions, provided=True)
        for name, source in self._spec.received_meshes.items():
            self._meshes[name] = Mesh(
                name,
                self._cfg.meshes[name].dimensions,
                provided=False,
                source=source,
                api_access=name in self._spec.api_access_meshes,
            )
        self._writes: set[Key] = set(self._spec.write_data)
        self._reads: set[Key] = set(self._spec.read_data)
        self._buffers: dict[Key, np.ndarray] = {}
        self._user_events: list[str] = []
        self._advance_calls = 0
        self._watch_points = WatchPoints(self._name, self._cfg, self._spec)
        self._watch_points.check(self._meshes)
        self._coupling = Coupling(self._name, self._degrees, self._log)
        self._scheme = build_schemes(self._coupling, self._cfg, self._name, extras)
        self._watch_points.open_logs()
        self._mappings: Mappings | None = None

    # ----------------------------------------------------------------- construction helpers

    def _log(self, message: str) -> None:
        out = sys.stdout
        if self._log_enabled and out is not None:
            with contextlib.suppress(OSError, ValueError):
                out.write(f"---[precice]  {message}\n")
                out.flush()

    def _data_dims(self, data: str, mesh: str) -> int:
        return data_dims(self._cfg, data, mesh)

    def _export_watch_points(self, t: float) -> None:
        store = self._coupling.store if self._coupling else None
        self._watch_points.export(t, self._meshes, store, self._degrees)

    # ----------------------------------------------------------------- validation (macros)

    def _hint_for_mesh(self, mesh: str) -> str:
        names = sorted(self._meshes)
        if len(names) == 1:
            return f' This participant only knows mesh "{names[0]}".'
        best = best_match(mesh, names)
        if best is not None and best[0] < 3:
            return f' Did you mean mesh "{best[1]}"?'
        return f" Available meshes are: {', '.join(names)}"

    def _validate_mesh(self, mesh: str) -> Mesh:
        try:
            return self._meshes[mesh]
        except KeyError:
            raise PreciceError(
                f'The mesh named "{mesh}" is unknown to preCICE.{self._hint_for_mesh(mesh)}'
            ) from None

    def _validate_data(self, mesh: str, data: str) -> None:
        self._validate_mesh(mesh)
        known = self._cfg.meshes[mesh].data
        if data not in known:
            others = [m for m in sorted(self._meshes) if data in self._cfg.meshes[m].data]
            best = best_match(data, known)
            if others:
                hint = f' Did you mean the data of mesh "{others[0]}"?'
            elif len(known) == 1:
                hint = f' This mesh only knows data "{known[0]}".'
            elif best is not None and best[0] < 3:
                hint = f' Did you mean data "{best[1]}"?'
            else:
                hint = f" Available data are: {', '.join(known)}"
            raise PreciceError(
                f'The given data "{data}" is unknown to preCICE mesh "{mesh}".{hint}'
            )

    def _require_mesh_modify(self, mesh_name: str) -> Mesh:
        mesh = self._validate_mesh(mesh_name)
        if not mesh.provided:
            raise PreciceError(
                f'This participant does not provide Mesh "{mesh_name}", but attempted to modify '
                f'it. Please add a provide-mesh tag as follows <provide-mesh name="{mesh_name}" />.'
            )
        if self._state != "constructed":
            raise PreciceError(
                f'This participant attempted to modify the Mesh "{mesh_name}" while locked. '
                "Mesh modification is only allowed before calling initialize()."
            )
        return mesh

    def _require_data_access(self, mesh_name: str, data: str, write: bool) -> Mesh:
        mesh = self._validate_mesh(mesh_name)
        if not (mesh.provided or mesh.api_access):
            raise PreciceError(
                f'This participant does not provide Mesh "{mesh_name}" nor does it enable direct '
                "access to it. To provide the mesh add a provide-mesh tag as follows "
                f'<provide-mesh name="{mesh_name}" />. To enable direct access to the mesh please '
                f'add a receive-mesh tag as follows <receive-mesh name="{mesh_name}" from="..." '
                'api-access="true" />, or modify an existing one. '
            )
        self._validate_data(mesh_name, data)
        allowed = self._writes if write else self._reads
        if (data, mesh_name) not in allowed:
            verb, tag = ("write", "write-data") if write else ("read", "read-data")
            raise PreciceError(
                f'This participant does not use data "{data}" via mesh "{mesh_name}", but '
                f"attempted to {verb} it. Please extend the configuration of participant "
                f'"{self._name}" by defining <{tag} mesh="{mesh_name}" name="{data}" /> or check '
                "if the data is defined on this mesh."
            )
        return mesh

    def _require_direct_access(
        self, mesh_name: str, function: str, what: str, preposition: str = "from mesh"
    ) -> Mesh:
        mesh = self._validate_mesh(mesh_name)
        if mesh.provided or not mesh.api_access:
            raise PreciceError(
                f'This participant attempteded to {what} (via "{function}") {preposition} '
                f'"{mesh_name}", but mesh "{mesh_name}" is either not a received mesh or its api '
                f"access was not enabled in the configuration. {function}(...) is only valid for "
                f'(<receive-mesh name="{mesh_name}" ... api-access="true"/>).'
            )
        return mesh

    def _require_experimental(self, function: str) -> None:
        if not self._experimental:
            raise PreciceError(
                f'You called the API function "{function}", which is part of the experimental '
                "API. You may unlock the full API by specifying <precice-configuration "
                'experimental="true" ... > in the configuration. Please be aware that '
                "experimental features may change in any future version (even minor or bugfix)."
            )

    def _check_ongoing(self) -> bool:
        return self._scheme.is_ongoing()

    def _alive(self, call: str) -> None:
        """After ``finalize()`` preCICE has dropped its state: calls that use it crash."""
        if self._state == "finalized":
            fatal("segfault", f"{call} cannot be called after finalize().")

    # ----------------------------------------------------------------- steering

    def initialize(self) -> None:
        """Connect to the partners, exchange meshes and initial data; blocks until they do."""
        if self._state == "finalized":
            raise PreciceError("initialize() cannot be called after finalize().")
        if self._state == "initialized":
            raise PreciceError("initialize() may only be called once.")
        scheme = self._scheme
        if scheme.action_required(INITIALIZE_DATA) and not scheme.action_fulfilled(INITIALIZE_DATA):
            raise PreciceError(
                "Initial data has to be written to preCICE before calling initialize(). After "
                "defining your mesh, call requiresInitialData() to check if the participant is "
                "required to write initial data using the writeData() function."
            )
        if self._user_events:
            raise PreciceError(
                "There are unstopped user defined events. Please stop them using "
                "stopLastProfilingSection() before calling initialize()."
            )
        coupling = self._coupling
        assert coupling is not None
        self._log("Setting up primary communication to coupling partner/s")
        rendezvous = Rendezvous(self._name, self._cfg, self._meshes, self._config_hash)
        rendezvous.connect(coupling, (p for s in scheme.schemes for p in s.partners))
        self._log("Primary ranks are connected")
        rendezvous.exchange_meshes(coupling)
        for mesh in self._meshes.values():
            if mesh.api_access and mesh.region is None and not self._mapped(mesh.name):
                raise PreciceError(
                    "You are running this participant in serial mode and the bounding box on "
                    f'mesh "{mesh.name}", is empty. Did you call setMeshAccessRegion with valid '
                    "data?"
                )
        for (data, mesh_name), buf in list(self._buffers.items()):
            self._buffers[(data, mesh_name)] = self._resized(buf, data, mesh_name)
        for mesh in self._meshes.values():
            for data in self._cfg.meshes[mesh.name].data:
                coupling.shapes[(data, mesh.name)] = (mesh.n, self._data_dims(data, mesh.name))
        self._mappings = Mappings(
            self._name, self._cfg, self._spec, self._meshes, self._reads, self._writes, self._log
        )
        for key in self._writes:
            coupling.store.wave(key).set(0.0, self._buffer(*key).copy())
        self._mappings.map_written(coupling.store, after=None)
        scheme.initialize()
        self._mappings.map_read(coupling.store)
        self._export_watch_points(0.0)
        self._reset_written()
        self._state = "initialized"
        self._log(scheme.state_text())

    def advance(self, computed_timestep_length: float) -> None:
        """Tell preCICE the solver computed ``dt``; at a window end, exchange data (blocks)."""
        dt = float(computed_timestep_length)
        if self._user_events:
            raise PreciceError(
                "There are unstopped user defined events. Please stop them using "
                "stopLastProfilingSection() before calling advance()."
            )
        if self._state == "constructed":
            fatal("segfault", "initialize() has to be called before advance().")
        if self._state == "finalized":
            fatal("segfault", "advance() cannot be called after finalize().")
        scheme = self._scheme
        if not scheme.is_ongoing():
            raise PreciceError("advance() cannot be called when isCouplingOngoing() returns false.")
        if not math.isfinite(dt):
            raise PreciceError("advance() cannot be called with an infinite time step size.")
        if equals(dt, 0.0):
            raise PreciceError("advance() cannot be called with a time step size of 0.")
        if dt < 0.0:
            raise PreciceError(f"advance() cannot be called with a negative time step size {dt!r}.")
        self._advance_calls += 1
        at_window_end = scheme.add_computed_time(dt)
        stepped_to = scheme.get_time()
        window_start = scheme.window_start()
        coupling = self._coupling
        assert coupling is not None
        if at_window_end or scheme.requires_substeps():
            for key in self._writes:
                coupling.store.wave(key).set(stepped_to, self._buffer(*key).copy())
        self._reset_written()
        if at_window_end:
            self._mappings.map_written(coupling.store, after=window_start)
        scheme.first_exchange()
        scheme.second_exchange()
        if at_window_end:
            after = scheme.get_time()
            complete = scheme.is_window_complete()
            if complete:
                start = scheme.window_start()
                for wave in coupling.store.waves.values():
                    wave.trim_before(start)
            else:
                for key in self._writes:
                    coupling.store.wave(key).trim_after(after)
                for mapping, data in self._mappings.write:
                    coupling.store.wave((data, mapping.spec.to_mesh)).trim_after(after)
            self._mappings.map_read(coupling.store)
            if complete:
                self._export_watch_points(after)
        self._log(scheme.state_text())

    def finalize(self) -> None:
        """Close the connections; the partners are not waited for (like preCICE's default)."""
        if self._state == "finalized":
            fatal("abort", "finalize() may only be called once.")
        self._user_events.clear()
        if self._state == "initialized" and self._coupling is not None:
            self._log("Close communication channels")
            for ch in self._coupling.channels.values():
                ch.close()
        self._state = "finalized"

    def __del__(self) -> None:
        # Like the real destructor: an unfinalized participant still closes its connections.
        coupling = getattr(self, "_coupling", None)
        if coupling is not None:
            with contextlib.suppress(Exception):
                for ch in coupling.channels.values():
                    ch.close()

    # ----------------------------------------------------------------- status queries

    def get_mesh_dimensions(self, mesh_name: str) -> int:
        self._alive("getMeshDimensions()")
        return self._validate_mesh(convert(mesh_name)).dims

    def get_data_dimensions(self, mesh_name: str, data_name: str) -> int:
        self._alive("getDataDimensions()")
        mesh, data = convert(mesh_name), convert(data_name)
        self._validate_data(mesh, data)
        return self._data_dims(data, mesh)

    def is_coupling_ongoing(self) -> bool:
        if self._state == "finalized":
            fatal("abort", "isCouplingOngoing() cannot be called after finalize().")
        if self._state != "initialized":
            fatal(
                "abort",
                "initialize() has to be called before isCouplingOngoing() can be evaluated.",
            )
        return self._scheme.is_ongoing()

    def is_time_window_complete(self) -> bool:
        if self._state == "constructed":
            fatal("abort", "initialize() has to be called before isTimeWindowComplete().")
        if self._state == "finalized":
            fatal("abort", "isTimeWindowComplete() cannot be called after finalize().")
        return self._scheme.is_window_complete()

    def get_max_time_step_size(self) -> float:
        if self._state == "finalized":
            fatal("abort", "getMaxTimeStepSize() cannot be called after finalize().")
        if self._state != "initialized":
            fatal(
                "abort",
                "initialize() has to be called before getMaxTimeStepSize() can be evaluated.",
            )
        return float(self._scheme.next_max())

    def requires_initial_data(self) -> bool:
        if self._state != "constructed":
            fatal("abort", "requiresInitialData() has to be called before initialize().")
        required = self._scheme.action_required(INITIALIZE_DATA)
        if required:
            self._scheme.mark_fulfilled(INITIALIZE_DATA)
        return required

    def requires_writing_checkpoint(self) -> bool:
        if self._state != "initialized":
            fatal("abort", "initialize() has to be called before requiresWritingCheckpoint().")
        required = self._scheme.action_required(WRITE_CHECKPOINT)
        if required:
            self._scheme.mark_fulfilled(WRITE_CHECKPOINT)
        return required

    def requires_reading_checkpoint(self) -> bool:
        if self._state != "initialized":
            fatal("abort", "initialize() has to be called before requiresReadingCheckpoint().")
        required = self._scheme.action_required(READ_CHECKPOINT)
        if required:
            self._scheme.mark_fulfilled(READ_CHECKPOINT)
        return required

    # ----------------------------------------------------------------- mesh access

    def requires_mesh_connectivity_for(self, mesh_name: str) -> bool:
        """True where a projection-based mapping would need edges/triangles of this mesh."""
        self._alive("requiresMeshConnectivityFor()")
        mesh = convert(mesh_name)
        self._validate_mesh(mesh)
        for participant in self._cfg.participants.values():
            for mapping in participant.mappings:
                if mapping.method not in CONNECTIVITY_METHODS:
                    continue
                conservative = mapping.constraint == "conservative"
                if (mapping.to_mesh if conservative else mapping.from_mesh) == mesh:
                    return True
        return False

    def set_mesh_vertex(self, mesh_name: str, position: Any) -> int:
        check_array_like(position, "position", "set_mesh_vertex")
        self._alive("setMeshVertex()")
        name = convert(mesh_name)
        if len(position) > 0:
            dimensions = len(position)
            expected = self.get_mesh_dimensions(name)
            assert dimensions == expected, (
                "Dimensions of vertex coordinate in set_mesh_vertex does not match with "
                "dimensions in problem definition. Provided dimensions: "
                f"{dimensions}, expected dimensions: {expected}"
            )
        mesh = self._require_mesh_modify(name)
        pos = np.asarray(position, dtype=np.float64).reshape(-1)
        if len(pos) != mesh.dims:
            raise PreciceError(
                f'Cannot set vertex for mesh "{name}". Expected {mesh.dims} position components '
                f"but found {len(pos)}."
            )
        return int(mesh.add(pos)[0])

    def get_mesh_vertex_size(self, mesh_name: str) -> int:
        self._alive("getMeshVertexSize()")
        name = convert(mesh_name)
        mesh = self._validate_mesh(name)
        if self._state != "initialized" and not mesh.provided:
            raise PreciceError(
                "initialize() has to be called before accessing data of the received mesh "
                f'"{name}" on participant "{self._name}".'
            )
        if not mesh.provided and mesh.api_access:
            return len(mesh.in_region())
        return mesh.n

    def set_mesh_vertices(self, mesh_name: str, positions: Any) -> np.ndarray:
        check_array_like(positions, "positions", "set_mesh_vertices")
        self._alive("setMeshVertices()")
        name = convert(mesh_name)
        if not isinstance(positions, np.ndarray):
            positions = np.asarray(positions)
        if len(positions) > 0:
            _size, dimensions = positions.shape
            expected = self.get_mesh_dimensions(name)
            assert dimensions == expected, (
                "Dimensions of vertex coordinates in set_mesh_vertices does not match with "
                f"dimensions in problem definition. Provided dimensions: {dimensions}, expected "
                f"dimensions: {expected}"
            )
        else:
            self.get_mesh_dimensions(name)
        mesh = self._require_mesh_modify(name)
        return mesh.add(np.asarray(positions, dtype=np.float64).reshape(-1, mesh.dims))

    def _connectivity(self, mesh_name: str, vertex_ids: Iterable[int], per: int) -> None:
        self._alive("setting mesh connectivity")
        mesh = self._require_mesh_modify(mesh_name)
        if not self.requires_mesh_connectivity_for(mesh_name):
            return
        ids = [int(v) for v in vertex_ids]
        if len(ids) % per:
            raise PreciceError(
                f'Cannot interpret passed vertex IDs attempting to set connectivity of mesh "'
                f'{mesh_name}". You passed {len(ids)} vertex indices, but we expected a '
                f"multiple of {per}."
            )
        for vid in ids:
            if not 0 <= vid < mesh.n:
                raise PreciceError(
                    f'The given VertexID "{vid}" is invalid. Check that it originated from a '
                    "call to setMeshVertex() or setMeshVertices()."
                )

    def _connectivity_rows(self, mesh_name: str, vertices: Any, per: int, api: str) -> None:
        """``set_mesh_edges``/``quads``/``tetrahedra``: rows of ``per`` vertex ids, checked
        for their shape as pyprecice does before it calls preCICE."""
        check_array_like(vertices, "vertices", api)
        arr = np.asarray(vertices)
        if len(arr) > 0:
            _, n = arr.shape
            assert n == per, (
                f"Provided vertices are not of a [N x {per}] format, but instead of a [N x {n}]"
            )
        self._connectivity(convert(mesh_name), arr.reshape(-1), per)

    def set_mesh_edge(self, mesh_name: str, first_vertex_id: int, second_vertex_id: int) -> None:
        self._connectivity(convert(mesh_name), [first_vertex_id, second_vertex_id], 2)

    def set_mesh_edges(self, mesh_name: str, vertices: Any) -> None:
        self._connectivity_rows(mesh_name, vertices, 2, "set_mesh_edges")

    def set_mesh_triangle(
        self, mesh_name: str, first_vertex_id: int, second_vertex_id: int, third_vertex_id: int
    ) -> None:
        ids = [first_vertex_id, second_vertex_id, third_vertex_id]
        self._connectivity(convert(mesh_name), ids, 3)

    def set_mesh_triangles(self, mesh_name: str, vertices: Any) -> None:
        check_array_like(vertices, "vertices", "set_mesh_triangles")
        arr = np.asarray(vertices)
        self._connectivity(convert(mesh_name), arr.reshape(-1), 3)

    def set_mesh_quad(
        self,
        mesh_name: str,
        first_vertex_id: int,
        second_vertex_id: int,
        third_vertex_id: int,
        fourth_vertex_id: int,
    ) -> None:
        ids = [first_vertex_id, second_vertex_id, third_vertex_id, fourth_vertex_id]
        self._connectivity(convert(mesh_name), ids, 4)

    def set_mesh_quads(self, mesh_name: str, vertices: Any) -> None:
        self._connectivity_rows(mesh_name, vertices, 4, "set_mesh_quads")

    def set_mesh_tetrahedron(
        self,
        mesh_name: str,
        first_vertex_id: int,
        second_vertex_id: int,
        third_vertex_id: int,
        fourth_vertex_id: int,
    ) -> None:
        ids = [first_vertex_id, second_vertex_id, third_vertex_id, fourth_vertex_id]
        self._connectivity(convert(mesh_name), ids, 4)

    def set_mesh_tetrahedra(self, mesh_name: str, vertices: Any) -> None:
        self._connectivity_rows(mesh_name, vertices, 4, "set_mesh_tetrahedra")

    def reset_mesh(self, mesh_name: str) -> None:
        self._require_experimental("resetMesh")
        if not self._allow_remeshing:
            raise PreciceError(
                "Cannot reset meshes. This feature needs to be enabled using "
                '<precice-configuration experimental="1" allow-remeshing="1">.'
            )
        raise PreciceError("gymprecice's fake_precice does not model remeshing (reset_mesh).")

    # ----------------------------------------------------------------- data access

    def write_data(self, mesh_name: str, data_name: str, vertex_ids: Any, values: Any) -> None:
        check_array_like(vertex_ids, "vertex_ids", "write_data")
        check_array_like(values, "values", "write_data")
        self._alive("writeData(...)")
        mesh_n, data_n = convert(mesh_name), convert(data_name)
        if not isinstance(values, np.ndarray):
            values = np.asarray(values)
        if len(values) == 0:
            size = 0
        elif self.get_data_dimensions(mesh_n, data_n) == 1:
            size = values.flatten().shape[0]
        else:
            assert len(values.shape) == 2, (
                "Vector valued data has to be provided as a numpy array of shape [N x D] where "
                "N = number of vertices and D = number of dimensions."
            )
            size, dimensions = values.shape
            expected = self.get_data_dimensions(mesh_n, data_n)
            assert dimensions == expected, (
                "Dimensions of vector data in write_data do not match with dimensions in problem "
                f"definition. Provided dimensions: {dimensions}, expected dimensions: {expected}"
            )
        assert len(vertex_ids) == size, (
            "Vertex IDs are of incorrect length in write_data. Check length of vertex ids input. "
            f"Provided size: {vertex_ids.size}, expected size: {size}"
        )
        if self._state == "finalized":
            raise PreciceError("writeData(...) cannot be called after finalize().")
        if not (self._state == "constructed" or self._check_ongoing()):
            raise PreciceError(
                "Calling writeData(...) is forbidden if coupling is not ongoing, because the data "
                "you are trying to write will not be used anymore. You can fix this by always "
                "calling writeData(...) before the advance(...) call in your simulation loop or "
                "by using Participant::isCouplingOngoing() to implement a safeguard."
            )
        mesh = self._require_data_access(mesh_n, data_n, write=True)
        ids = as_vertex_ids(vertex_ids)
        if size == 0:
            return
        dim = self._data_dims(data_n, mesh_n)
        flat = np.asarray(values, dtype=np.float64).reshape(-1)
        if flat.size != size * dim:
            raise PreciceError(
                f'Input sizes are inconsistent attempting to write {dim}D data "{data_n}" to '
                f'mesh "{mesh_n}". You passed {len(ids)} vertex indices and {flat.size} data '
                f"components, but we expected {size * dim} data components ({dim} x {len(ids)})."
            )
        invalid = np.nonzero((ids < 0) | (ids >= mesh.n))[0]
        if len(invalid):
            raise PreciceError(
                f'Cannot write data "{data_n}" to mesh "{mesh_n}" due to invalid Vertex ID at '
                f"vertices[{int(invalid[0])}]. Please make sure you only use the results from "
                "calls to setMeshVertex/Vertices()."
            )
        buf = self._buffer(data_n, mesh_n)
        buf[ids] = flat.reshape(-1, dim)

    def read_data(
        self, mesh_name: str, data_name: str, vertex_ids: Any, relative_read_time: float
    ) -> np.ndarray:
        check_array_like(vertex_ids, "vertex_ids", "read_data")
        self._alive("readData(...)")
        mesh_n, data_n = convert(mesh_name), convert(data_name)
        dims = self.get_data_dimensions(mesh_n, data_n)
        size = len(vertex_ids)
        rel = float(relative_read_time)
        if self._state == "constructed":
            raise PreciceError("readData(...) cannot be called before initialize().")
        if self._state == "finalized":
            raise PreciceError("readData(...) cannot be called after finalize().")
        scheme = self._scheme
        if not (rel - scheme.next_max() <= NUMERICAL_ZERO):
            raise PreciceError("readData(...) cannot sample data outside of current time window.")
        if rel < 0:
            raise PreciceError("readData(...) cannot sample data before the current time.")
        if not (scheme.is_ongoing() or equals(rel, 0.0)):
            raise PreciceError(
                f"Calling readData(...) with relativeReadTime = {rel!r} is forbidden if coupling "
                "is not ongoing. If coupling finished, only data for relativeReadTime = 0 is "
                "available. Please always use precice.getMaxTimeStepSize() to obtain the maximum "
                "allowed relativeReadTime."
            )
        mesh = self._require_data_access(mesh_n, data_n, write=False)
        if size == 0:
            return np.zeros(0)
        assert self._coupling is not None
        wave = self._coupling.store.wave((data_n, mesh_n))
        if not len(wave):
            raise PreciceError(
                f'Data "{data_n}" cannot be read from mesh "{mesh_n}" as it contains no samples. '
                "This is typically a configuration issue of the data flow. Check if the data is "
                f'correctly exchanged to this participant "{self._name}" and mapped to mesh '
                f'"{mesh_n}".'
            )
        ids = as_vertex_ids(vertex_ids)
        invalid = np.nonzero((ids < 0) | (ids >= mesh.n))[0]
        if len(invalid):
            raise PreciceError(
                f'Cannot read data "{data_n}" from mesh "{mesh_n}" due to invalid Vertex ID at '
                f"vertices[{int(invalid[0])}]. Please make sure you only use the results from "
                "calls to setMeshVertex/Vertices()."
            )
        values = wave.sample(scheme.get_time() + rel, self._degrees[data_n])[ids]
        out = np.array(values, dtype=np.float64)
        return out.reshape(size) if dims == 1 else out.reshape(size, dims)

    def write_and_map_data(
        self, mesh_name: str, data_name: str, coordinates: Any, values: Any
    ) -> None:
        self._require_experimental("writeAndMapData")
        raise PreciceError("gymprecice's fake_precice does not model just-in-time mappings.")

    def map_and_read_data(
        self, mesh_name: str, data_name: str, coordinates: Any, relative_read_time: float
    ) -> np.ndarray:
        self._require_experimental("mapAndReadData")
        raise PreciceError("gymprecice's fake_precice does not model just-in-time mappings.")

    def write_gradient_data(
        self, mesh_name: str, data_name: str, vertex_ids: Any, gradients: Any
    ) -> None:
        self._require_experimental("writeGradientData")
        if self._state == "finalized":
            raise PreciceError("writeGradientData(...) cannot be called after finalize().")
        self._require_data_access(convert(mesh_name), convert(data_name), write=True)
        # No data of the double carries gradients, so (like preCICE then) this is a no-op.

    def requires_gradient_data_for(self, mesh_name: str, data_name: str) -> bool:
        self._alive("requiresGradientDataFor()")
        self._validate_data(convert(mesh_name), convert(data_name))
        return False

    def set_mesh_access_region(self, mesh_name: str, bounding_box: Any) -> None:
        check_array_like(bounding_box, "bounding_box", "set_mesh_access_region")
        self._alive("setMeshAccessRegion()")
        name = convert(mesh_name)
        box = np.asarray(bounding_box, dtype=np.float64).reshape(-1)
        assert len(box) > 0, "Bounding box cannot be empty."
        assert len(box) == self.get_mesh_dimensions(name) * 2, (
            "Dimensions of bounding box in set_mesh_access_region does not match with dimensions "
            "in problem definition."
        )
        mesh = self._require_direct_access(
            name, "setMeshAccessRegion", "set an access region", preposition="on mesh"
        )
        if self._state == "finalized":
            raise PreciceError("setMeshAccessRegion() cannot be called after finalize().")
        if self._state == "initialized":
            raise PreciceError("setMeshAccessRegion() needs to be called before initialize().")
        if mesh.region is not None:
            raise PreciceError(
                f'A mesh access region was already defined for mesh "{name}". '
                "setMeshAccessRegion may only be called once per mesh."
            )
        if np.any(box[0::2] > box[1::2]):
            raise PreciceError(
                "Your bounding box is ill defined, i.e. it has a negative volume. The required "
                "format is [x_min, x_max...]"
            )
        mesh.region = box

    def get_mesh_vertex_ids_and_coordinates(self, mesh_name: str) -> tuple[np.ndarray, np.ndarray]:
        self._alive("getMeshVertexIDsAndCoordinates()")
        name = convert(mesh_name)
        size = self.get_mesh_vertex_size(name)
        dims = self.get_mesh_dimensions(name)
        mesh = self._require_direct_access(
            name, "getMeshVertexIDsAndCoordinates", "get mesh vertex IDs and coordinates"
        )
        inside = mesh.in_region()
        assert len(inside) == size
        ids = inside.astype(np.int32)
        coords = np.array(mesh.coordinates[inside], dtype=np.float64).reshape(size, dims)
        return ids, coords

    # ----------------------------------------------------------------- profiling

    def start_profiling_section(self, event_name: str) -> None:
        name = convert(event_name)
        if "/" in name:
            fatal(
                "abort", f'The provided section name "{name}" may not contain a forward-slash "/"'
            )
        self._user_events.append(name)

    def stop_last_profiling_section(self) -> None:
        if not self._user_events:
            fatal("abort", "There is no user-started event to stop.")
        self._user_events.pop()

    # ----------------------------------------------------------------- internals

    def _buffer(self, data: str, mesh_name: str) -> np.ndarray:
        key = (data, mesh_name)
        buf = self._buffers.get(key)
        resized = self._resized(buf, data, mesh_name)
        if resized is not buf:
            self._buffers[key] = resized
        return resized

    def _resized(self, buf: np.ndarray | None, data: str, mesh_name: str) -> np.ndarray:
        n = self._meshes[mesh_name].n
        dim = self._data_dims(data, mesh_name)
        if buf is not None and buf.shape == (n, dim):
            return buf
        new = np.zeros((n, dim))
        if buf is not None:
            k = min(len(buf), n)
            new[:k] = buf[:k]
        return new

    def _reset_written(self) -> None:
        for buf in self._buffers.values():
            buf.fill(0.0)

    def _mapped(self, mesh_name: str) -> bool:
        return any(mesh_name in (m.from_mesh, m.to_mesh) for m in self._spec.mappings)


def _logs_errors(method: Any) -> Any:
    """preCICE logs every error it throws; do the same once per error, then re-raise."""

    @functools.wraps(method)
    def wrapper(self: Participant, *args: Any, **kwargs: Any) -> Any:
        try:
            return method(self, *args, **kwargs)
        except PreciceError as exc:
            if not getattr(exc, "logged", False):
                exc.logged = True  # type: ignore[attr-defined]
                self._log(f"ERROR: {exc}")
            raise

    return wrapper


for _name, _method in list(vars(Participant).items()):
    if callable(_method) and not _name.startswith("_"):
        setattr(Participant, _name, _logs_errors(_method))
del _name, _method
