"""What core tells a plugin about one solver, and what a plugin hands back.

These small value types are the whole vocabulary of the hook specs
(:mod:`gymprecice.hookspecs`): a plugin reads a :class:`SolverContext`, and answers with a
:class:`LaunchSpec` (how to start the solver), an :class:`InterfaceGeometry` (where the
controller's vertices are), an :class:`OutputReader` (observations from solver files) or a
:class:`DoctorCheck` (one line of ``gymprecice doctor``).
Core owns processes and preCICE; plugins only describe.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

import numpy as np

if TYPE_CHECKING:
    from gymprecice.plugin.precice_xml import PreciceConfig

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

    Core builds the context at two moments, and the paths differ:

    | field | validation (``validate_case``) | run time (every other hook) |
    | --- | --- | --- |
    | ``run_dir`` | the pristine solver directory | ``<run_root>/env_<i>/<path>``, the env's real copy |
    | ``source_dir`` | the pristine solver directory | the same (never write it) |
    | ``env_dir`` | the case directory | ``<run_root>/env_<i>`` |
    | ``precice_config_file`` | the case's preCICE file | the env's copy (its own exchange directory) |
    | ``precice`` | parsed from the case's file | the same content |
    | ``rng`` | ``None`` | the episode's seeded generator (set before ``reset_case``) |

    The other fields are the same at both moments:

    ``name``
        The solver's key under ``physics_simulation_engine.solvers``.
    ``kind``
        Its ``kind``; a plugin answers only for its own kinds.
    ``env_index``
        The env's index (0 at validation).
    ``participant``
        The preCICE participant the solver plays (``None`` if the configuration names none).
    ``options``
        The solver's ``options`` object from ``gymprecice-config.json``, untouched: refusing
        unknown keys is the plugin's job (:mod:`gymprecice.options`).
    ``config_file``
        The ``gymprecice-config.json`` (``None`` for a configuration given as a dict):
        name it in error messages about options.
    ``precice``
        The parsed preCICE configuration (:class:`gymprecice.precice_xml.PreciceConfig`:
        ``participants``, ``meshes``, ``data``, ``coupling_schemes``, ``m2n`` and
        helpers such as ``participant(name)``, ``end_time(participant)``,
        ``time_window_size(participant)``, ``data_dimension(data, mesh)``).
    ``reset_options``
        The ``options`` given to ``env.reset`` (``{}`` otherwise).
    ``state``
        The plugin's own memory for this solver across hooks and episodes.
    ``precice_library``
        The module the env couples through (see the field's comment).
    ``fields``, ``field_interval``
        What the env renders from this solver, and how often (see the fields' comments).
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
    #: The fields the env draws from this solver (``render_mode="rgb_array"``), set by core
    #: before every ``gymprecice_reset_case``; ``()`` when the env does not render: then
    #: the solver must write nothing extra (see ``gymprecice_read_field``).
    fields: tuple[str, ...] = ()
    #: Coupling time in seconds between two frames (one action), when ``fields`` is set.
    field_interval: float | None = None

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

    ``argv`` (program and arguments, strings or paths; the program is looked up on
    ``PATH`` unless it contains a ``/``) runs in ``cwd`` (inside ``solver.run_dir``) with
    ``env`` added to the (MPI-cleaned) environment, its stdout and stderr going to the file
    ``log_name`` (a plain name) in ``cwd``, truncated at each launch. Core adds
    ``GYMPRECICE_PRECICE_LIBRARY`` unless ``env`` sets it.
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
    flow rate into a velocity profile. ``patches`` names the solver's boundary patches the
    vertices come from, for messages.
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

    What ``gymprecice_open_output`` returns and ``Adapter.open_output`` hands to env code.
    Required: ``read_new()`` returns the rows not returned before (possibly none);
    ``close()`` releases file handles. Core closes every reader it handed out at
    reset and close. What a "row" is belongs to the plugin and is documented with its
    reader: the OpenFOAM plugin's :class:`~gymprecice_openfoam.outputs.Rows` has ``time``,
    ``values``, ``column(name)`` and ``last`` (the newest row's values); the watch-point
    reader returns a float array, one row per line.

    Every reader gymprecice ships also follows :class:`WaitableOutputReader`, and env code
    (the examples and the tutorials) relies on it; a plugin's reader should too.
    """

    def read_new(self) -> Any: ...

    def close(self) -> None: ...


@runtime_checkable
class WaitableOutputReader(OutputReader, Protocol):
    """The conventions env code relies on to read the output of the step that just ended.

    ``start_time``
        The time, in the output's own time axis, at which the episode starts: the output
        of env time ``t`` (``Adapter.time``, which counts from 0 each episode) is at
        ``start_time + t``. ``None`` means 0. An OpenFOAM case continuing from a pre-run
        to t = 1.0 has ``start_time == 1.0``; a preCICE watch-point log starts at 0.
    ``latest_time``
        Time of the newest row handed out so far (by ``read_new`` or ``wait_until``),
        ``None`` before the first.
    ``wait_until(time, timeout)``
        Block until the row at ``time`` (or a later one) has been written, then return the
        rows of the step that ended at ``time``: the rows not returned before, up to the
        row at ``time`` (:func:`gymprecice.readers.rows_through` makes the cut). Rows the
        solver wrote past ``time`` (it may run ahead of the controller) stay for the next
        read, so what an env takes from a step never depends on how far the solver got.
        A second call for the same ``time`` returns the same rows, so an env's
        observation and reward may both ask. Raise an error naming the file after
        ``timeout`` seconds. Core counts the time spent here as waiting for the solver
        (``info["timing"]["wait_s"]``), not as env code.
    """

    start_time: float | None

    @property
    def latest_time(self) -> float | None: ...

    def wait_until(self, time: float, timeout: float) -> Any: ...


@dataclass
class DoctorCheck:
    """One line of ``gymprecice doctor``: what was looked for, what was found, what to do.

    ``name``: what was looked for (``"OpenFOAM"``); ``ok``: found and usable; ``detail``:
    what was found (a version, a path); ``advice``: what to do when not ``ok`` (needed
    then); ``required``: whether gymprecice cannot work without it (``doctor`` fails).
    """

    name: str
    ok: bool
    detail: str = ""
    advice: str = ""
    required: bool = False
