"""What core tells a plugin about one solver, and what a plugin hands back.

These small value types are the whole vocabulary of the hook specs
(:mod:`gymprecice.hookspecs`): a plugin reads a :class:`SolverContext`, and answers with a
:class:`LaunchSpec` (how to start the solver), an :class:`InterfaceGeometry` (where the
controller's vertices are) or an :class:`OutputReader` (observations from solver files).
Core owns processes and preCICE; plugins only describe.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

import numpy as np

if TYPE_CHECKING:
    from gymprecice.precice_xml import PreciceConfig

#: The module name of gymprecice's pyprecice test double (``precice.library`` selects it).
TEST_DOUBLE_LIBRARY = "gymprecice.testing.fake_precice"
#: Environment variable naming the preCICE module: read by core (it overrides the
#: configuration's ``precice.library`` for the env's side) and set by core in every solver
#: process it launches, so a Python solver can import the same library.
LIBRARY_ENV_VAR = "GYMPRECICE_PRECICE_LIBRARY"


@dataclass
class SolverContext:
    """One solver of one environment, as plugins see it.

    ``source_dir`` is the pristine case and must never be written; everything a plugin
    changes lives under ``run_dir`` (the env's own real copy of the solver directory).
    """

    name: str
    kind: str
    run_dir: Path
    source_dir: Path
    env_dir: Path
    env_index: int = 0
    participant: str | None = None
    options: dict[str, Any] = field(default_factory=dict)
    config_file: Path | None = None
    precice: PreciceConfig | None = None
    precice_config_file: Path | None = None
    rng: np.random.Generator | None = None
    reset_options: dict[str, Any] = field(default_factory=dict)
    #: Anything a plugin wants to keep between hooks for this solver (e.g. the initial time).
    state: dict[str, Any] = field(default_factory=dict)
    #: The module the env's coupling imports as ``precice``: ``"precice"`` (real pyprecice)
    #: or ``"gymprecice.testing.fake_precice"`` (the test double). Every participant of a run
    #: must use the same one; core also exports it to the solver's process as
    #: ``GYMPRECICE_PRECICE_LIBRARY``.
    precice_library: str = "precice"

    @property
    def uses_test_double(self) -> bool:
        """Whether the env couples through gymprecice's preCICE test double."""
        return self.precice_library == TEST_DOUBLE_LIBRARY

    def describe(self) -> str:
        """Short label for error messages: ``solver 'fluid' (openfoam) of env 3``."""
        return f"solver {self.name!r} ({self.kind}) of env {self.env_index}"


@dataclass
class LaunchSpec:
    """How to start one solver process; core runs it in its own process group.

    ``argv`` runs in ``cwd`` with ``env`` added to the (MPI-cleaned) environment, its
    stdout and stderr going to ``log_name`` inside the solver's run directory.
    """

    argv: Sequence[str]
    cwd: Path
    env: Mapping[str, str] = field(default_factory=dict)
    log_name: str = "solver.log"


@dataclass
class InterfaceGeometry:
    """Vertices of one controller interface, in the order data will be written/read.

    ``coordinates`` has shape ``(n, dimensions)``. Face-based solvers also give
    ``normals`` (unit, ``(n, 3)``) and ``areas`` (``(n,)``), which actuators need to turn a
    flow rate into a velocity profile.
    """

    coordinates: np.ndarray
    normals: np.ndarray | None = None
    areas: np.ndarray | None = None
    patches: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        self.coordinates = np.asarray(self.coordinates, dtype=float)
        if self.coordinates.ndim != 2:
            raise ValueError(
                f"interface coordinates must be a 2-D array (n, dim), got shape {self.coordinates.shape}"
            )

    @property
    def area_vectors(self) -> np.ndarray | None:
        """Face area vectors ``normals * areas`` (``None`` unless both are known)."""
        if self.normals is None or self.areas is None:
            return None
        return self.normals * np.asarray(self.areas)[:, None]


@runtime_checkable
class OutputReader(Protocol):
    """An incremental reader of a solver's output (probes, forces, watch points, ...).

    ``read_new`` returns only the rows written since the last call; ``close`` releases
    file handles. Core closes every reader it handed out at reset and close.
    """

    def read_new(self) -> Any: ...

    def close(self) -> None: ...


@dataclass
class DoctorCheck:
    """One line of ``gymprecice doctor``: what was looked for, what was found, what to do."""

    name: str
    ok: bool
    detail: str = ""
    advice: str = ""
    required: bool = False
