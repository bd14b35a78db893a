"""What each solver kind puts in a new package's case: :class:`KindCase`, the kinds
``gymprecice new`` knows (``command``, ``openfoam``, ``dealii``, ``fenics``) with the numbers
of their task, and the empty solver folder of any other installed kind.

The solver folders' file texts are the templates of :mod:`gymprecice.scaffold.templates`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from gymprecice.scaffold import templates as t

__all__ = [
    "COMMAND",
    "DEALII",
    "FENICS",
    "KNOWN_KINDS",
    "OPENFOAM",
    "KindCase",
    "command_argv",
    "other_kind",
]


def _along(n: int, start: tuple[float, float], end: tuple[float, float]) -> list[list[float]]:
    """``n`` points evenly inside the segment from ``start`` to ``end`` (not its ends)."""
    return [
        [
            round(start[0] + (end[0] - start[0]) * (i + 1) / (n + 1), 6),
            round(start[1] + (end[1] - start[1]) * (i + 1) / (n + 1), 6),
        ]
        for i in range(n)
    ]


@dataclass(frozen=True)
class KindCase:
    """What one solver kind puts in a new package's case, and the numbers of its task."""

    solver_name: str
    solver_dir: str
    participant: str
    mesh: str
    #: the data the controller writes and reads, whether each is a vector, their units
    write: str
    read: str
    write_vector: bool = False
    read_vector: bool = False
    write_unit: str = "no unit"
    read_unit: str = "no unit"
    #: the read mapping's constraint from the controller's actuators to the solver's mesh
    actuation_constraint: str = "consistent"
    options: dict[str, Any] = field(default_factory=dict)
    window: float = 0.05
    windows: int = 1
    end_time: float = 1.0
    #: an actuator at level a writes reference + actuation_scale * a
    reference: float = 0.0
    actuation_scale: float = 1.0
    setpoints: tuple[float, float] = (-0.5, 0.5)
    sensor_scale: float = 1.0
    #: the stand-in's model: a lag towards gain * (actuation - reference) in tau seconds
    gain: float = 1.0
    stand_in_reference: float = 0.0
    tau: float = 0.2
    total: bool = False
    actuators: Callable[[int], list[list[float]]] = lambda n: _along(n, (0, 0), (1, 0))
    sensors: tuple[tuple[float, float], ...] = ((0.25, 0.0), (0.75, 0.0))
    timeouts: dict[str, float] = field(
        default_factory=lambda: {"reset": 60, "progress": 30, "finalize": 10, "kill_grace": 2}
    )
    description: str = "hold a sensed value at a setpoint"
    task: str = ""
    actuation_text: str = ""
    sensing_text: str = ""
    solver_text: str = ""
    real_run_text: str = ""
    #: the solver folder's files, relative to it (rendered with the package's values)
    files: dict[str, str] = field(default_factory=dict)
    #: whether the solver is the package's own program (no stand-in needed)
    own_program: bool = False


def command_argv() -> list[str]:
    return [
        "{python}",
        "solver.py",
        "--participant",
        "{participant}",
        "--config",
        "{precice_config}",
    ]


COMMAND = KindCase(
    solver_name="solver",
    solver_dir="solver",
    participant="Solver",
    mesh="Solver-Mesh",
    write="Actuation",
    read="Response",
    options={"argv": command_argv(), "reset_timeout": 60, "log_name": "solver.log"},
    task="A system responds to its actuators with a lag (time constant 0.2 s); the agent "
    "must hold the mean of two sensed responses at a setpoint drawn each episode in "
    "[-0.5, 0.5].",
    actuation_text="sets each actuator's level",
    sensing_text="the response at two sensors",
    solver_text="The solver is `solver.py`, a Python program of the package's own that "
    "speaks the pyprecice v3 API (kind `command`): replace its model with yours, or its "
    "`argv` in `gymprecice-config.json` with your own program.",
    real_run_text="the same program on real preCICE (pyprecice)",
    own_program=True,
)

OPENFOAM = KindCase(
    solver_name="fluid",
    solver_dir="fluid-openfoam",
    participant="Fluid",
    mesh="Fluid-Mesh-inlet",
    write="Velocity",
    read="Pressure",
    write_vector=True,
    write_unit="m/s",
    read_unit="m^2/s^2",
    options={},
    window=0.01,
    windows=5,
    reference=0.1,
    actuation_scale=0.1,
    setpoints=(0.01, 0.05),
    sensor_scale=0.01,
    gain=0.3,
    tau=0.1,
    actuators=lambda n: _along(n, (0, 0), (0, 0.2)),
    sensors=((0.0, 0.05), (0.0, 0.15)),
    timeouts={"reset": 600, "progress": 120, "finalize": 30, "kill_grace": 2},
    description="hold a channel's inlet pressure at a setpoint",
    task="A 2-D channel (1 x 0.2 m, pimpleFoam, laminar); the agent sets the inlet "
    "velocity in [0, 0.2] m/s and must hold the inlet's kinematic pressure at a setpoint "
    "drawn each episode in [0.01, 0.05] m^2/s^2.",
    actuation_text="writes the inlet velocity",
    sensing_text="the pressure at two inlet points",
    solver_text="The solver is OpenFOAM (`pimpleFoam`, kind `openfoam`), its case "
    "`fluid-openfoam/`, coupled by the OpenFOAM-preCICE adapter.",
    real_run_text="OpenFOAM, preCICE and the OpenFOAM-preCICE adapter",
    files=t.OPENFOAM_FILES,
)

DEALII = KindCase(
    solver_name="solid",
    solver_dir="solid-dealii",
    participant="Solid",
    mesh="Solid-Mesh",
    write="Force",
    read="Displacement",
    write_vector=True,
    read_vector=True,
    write_unit="N",
    read_unit="m",
    actuation_constraint="conservative",
    options={},
    window=0.01,
    windows=5,
    actuation_scale=10.0,
    setpoints=(-0.005, 0.005),
    sensor_scale=0.001,
    gain=0.001,
    tau=0.3,
    total=True,
    actuators=lambda n: [[0.05, round(1.0 - 0.5 * i / n, 6)] for i in range(n)],
    sensors=((0.0, 1.0),),
    timeouts={"reset": 600, "progress": 120, "finalize": 30, "kill_grace": 2},
    description="hold an elastic flap's tip at a setpoint",
    task="An elastic flap (0.1 x 1 m, clamped at its foot); the agent pushes it sideways "
    "with forces in [-10, 10] N near its tip and must hold the tip's x displacement at a "
    "setpoint drawn each episode in [-5, 5] mm.",
    actuation_text="writes a force at each actuator",
    sensing_text="the tip's displacement",
    solver_text="The solver is the deal.II-preCICE adapter's `elasticity` program (kind "
    "`dealii`), configured by `solid-dealii/parameters.prm`.",
    real_run_text="the deal.II-preCICE adapter's `elasticity` and preCICE",
    files={"parameters.prm": t.DEALII_PARAMETERS},
)

FENICS = KindCase(
    solver_name="solid",
    solver_dir="solid-fenics",
    participant="Solid",
    mesh="Solid-Mesh",
    write="Temperature",
    read="Heat-Flux",
    write_unit="K",
    read_unit="W/m^2",
    options={"script": "solid.py"},
    window=0.01,
    windows=1,
    end_time=0.2,
    reference=310.0,
    actuation_scale=10.0,
    setpoints=(-3000.0, 3000.0),
    sensor_scale=1000.0,
    gain=-400.0,
    stand_in_reference=310.0,
    tau=0.03,
    sensors=((0.25, 0.0), (0.75, 0.0)),
    timeouts={"reset": 600, "progress": 120, "finalize": 30, "kill_grace": 2},
    description="hold a plate's surface heat flux at a setpoint",
    task="A heat-conducting plate (1 x 0.25 m, its bottom held at 310 K); the agent sets "
    "the temperature of its top edge in [300, 320] K and must hold the heat flux there at "
    "a setpoint drawn each episode in [-3000, 3000] W/m^2.",
    actuation_text="sets the top edge's temperature",
    sensing_text="the heat flux at two points of the top edge",
    solver_text="The solver is a FEniCS script (`solid-fenics/solid.py`, kind `fenics`), "
    "coupled through fenicsprecice.",
    real_run_text="the FEniCS solver environment (`gymprecice install fenics`) and preCICE",
    files={
        "solid.py": t.FENICS_SCRIPT,
        "precice-adapter-config.json": t.FENICS_ADAPTER_CONFIG,
    },
)

#: the kinds whose case ``gymprecice new`` knows; any other installed kind gets
#: :func:`other_kind`'s empty solver folder
KNOWN_KINDS: dict[str, KindCase] = {
    "command": COMMAND,
    "openfoam": OPENFOAM,
    "dealii": DEALII,
    "fenics": FENICS,
}


def other_kind(kind: str) -> KindCase:
    """A kind of a plugin the scaffold knows nothing about: its folder is the user's."""
    return KindCase(
        solver_name="solver",
        solver_dir="solver",
        participant="Solver",
        mesh="Solver-Mesh",
        write="Actuation",
        read="Response",
        options={},
        timeouts={"reset": 600, "progress": 120, "finalize": 30, "kill_grace": 2},
        task=COMMAND.task,
        actuation_text=COMMAND.actuation_text,
        sensing_text=COMMAND.sensing_text,
        solver_text=f"The solver is of kind `{kind}`; its folder `solver/` is yours to fill "
        "(see its README.md).",
        real_run_text=f"the solver of kind `{kind}` and preCICE",
        files={"README.md": t.SOLVER_README},
    )
