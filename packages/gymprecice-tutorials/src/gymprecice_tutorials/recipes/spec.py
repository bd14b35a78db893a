"""What a case recipe is: its parameters, and the packaged cases.

A :class:`CaseSpec` holds everything the files of a case are written from: the geometry,
the mesh resolution, the flow and the RL episode. :data:`CASES` names the packaged ones;
:func:`case_spec` returns one with fields replaced.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Literal

#: the packaged cases, written by :func:`gymprecice_tutorials.recipes.case.regenerate`
CASES_DIR = Path(__file__).resolve().parent.parent / "cases"
#: the OpenFOAM case inside a case directory, and the file that couples it (or not)
FLUID_DIR = "fluid-openfoam"
PRECICE_FO_FILE = "system/preciceAdapterFunctionObject"

#: "jets": two jets (patches jet1, jet2) set by the controller; "rotation": the whole
#: cylinder wall (patch cylinder) moves with the velocity the controller sets
Control = Literal["jets", "rotation"]
#: How one action reaches the solver (see :attr:`CaseSpec.coupling`).
Coupling = Literal["step", "action"]


@dataclass(frozen=True)
class Geometry:
    """Channel, cylinder and jets (lengths in metres, angles in degrees)."""

    length: float = 2.2
    height: float = 0.41
    diameter: float = 0.1
    centre: tuple[float, float] = (0.2, 0.2)
    #: extent of the 2D mesh in z (one cell); forces are per this depth
    depth: float = 0.01
    #: half side of the square box that holds the O-grid around the cylinder
    box_half: float = 0.1
    #: angular width of each jet; jets are centred at 90° and 270°
    jet_width: float = 10.0

    @property
    def radius(self) -> float:
        return self.diameter / 2

    def check(self) -> None:
        cx, cy = self.centre
        s = self.box_half
        if not self.radius < s:
            raise ValueError("box_half must be larger than the cylinder radius")
        if not (s < cx and s < cy and cy + s < self.height and cx + s < self.length):
            raise ValueError("the box around the cylinder must lie inside the channel")
        if not 0 < self.jet_width < 80:
            raise ValueError("jet_width must lie in (0, 80) degrees")


@dataclass(frozen=True)
class Resolution:
    """Mesh resolution knobs; every block count derives from these three numbers.

    * ``cells_per_jet``: cells across one jet (the jet width). The tangential spacing is
      uniform around the cylinder, so the wall has ``cells_per_jet * 360 / jet_width``
      faces (with or without jets); ``h_box`` is the resulting spacing along the box.
    * ``wall_cell``: height of the first cell at the cylinder wall, as a fraction of D.
      The O-grid cells grow geometrically from it to ``h_box`` at the box; their number
      follows (and the growth is then adjusted so that the last cell is ``h_box``).
    * ``wake_grading``: last/first cell size along x in the wake (first cell = ``h_box``);
      the inlet, top and bottom blocks are uniform with spacing ``h_box``.
    """

    cells_per_jet: int = 3
    wall_cell: float = 0.01
    wake_grading: float = 4.0

    @classmethod
    def coarse(cls) -> Resolution:
        """A few thousand cells: quick start, smoke tests."""
        return cls(cells_per_jet=2, wall_cell=0.02, wake_grading=6.0)

    @classmethod
    def default(cls) -> Resolution:
        """The training cases."""
        return cls()

    @classmethod
    def fine(cls) -> Resolution:
        """The validation against the Schäfer-Turek reference (docs/validation.md)."""
        return cls(cells_per_jet=4, wall_cell=0.0075, wake_grading=4.0)


@dataclass(frozen=True)
class Flow:
    """Inflow, viscosity and time stepping."""

    u_max: float = 1.5
    nu: float = 1e-3
    dt: float = 5e-4
    #: PIMPLE outer iterations per time step. 1 is PISO: cheaper, but its lagged
    #: convective flux over-predicts the lift amplitude by several per cent at dt = 5e-4
    #: (see docs/validation.md); 2 removes most of that error.
    outer_correctors: int = 2

    @property
    def u_mean(self) -> float:
        return 2.0 * self.u_max / 3.0


@dataclass(frozen=True)
class CaseSpec:
    """Everything that makes one tutorial case."""

    name: str
    control: Control
    geometry: Geometry = field(default_factory=Geometry)
    resolution: Resolution = field(default_factory=Resolution)
    flow: Flow = field(default_factory=Flow)
    #: RL episode: number of actions and solver time steps per action
    actions_per_episode: int = 80
    steps_per_action: int = 50
    #: ``"step"``: one preCICE time window per solver step (parallel-explicit); the
    #: controller writes every window and core's ``ramp`` schedule moves the actuator from
    #: the previous action to the new one. ``"action"``: one time window per action
    #: (serial-explicit, the controller first); the solver subcycles inside it, the OpenFOAM
    #: adapter reads the data at the end of each substep and preCICE interpolates the written
    #: action linearly across the window (``waveform-degree="1"``): the same ramp with
    #: ``steps_per_action`` times fewer exchanges.
    coupling: Coupling = "step"
    #: simulated time of the uncoupled pre-run that gives the developed-shedding snapshot
    prerun_end_time: float = 6.0
    #: optional episode starts (simulated times before ``prerun_end_time``) that the
    #: pre-run also writes: a library of developed-flow snapshots at different shedding
    #: phases. The OpenFOAM plugin splits them once into training starts and held-out
    #: evaluation starts (every fourth, ``eval_fraction`` 0.25), with a validation start
    #: halfway between two held-out ones (``validation_fraction`` 0.25) that chooses the
    #: model a training run keeps; training resets draw from the rest,
    #: ``gymprecice evaluate`` / ``baseline`` from the held-out ones. Empty: every episode
    #: starts from ``prerun_end_time``.
    snapshots: tuple[float, ...] = ()
    #: the OpenFOAM plugin's divergence guard: an episode whose Courant number passes this
    #: ends as diverged (terminated, with the env's penalty) before the flow turns to
    #: infinities. The cylinders run far below 1; an action that blows the flow up
    #: drives it past 1e30 within a few steps. None: no guard
    max_courant: float | None = 20.0
    n_procs: int = 2
    #: write fields every this many seconds of simulated time (0: only at endTime)
    write_interval: float = 0.0
    #: controlDict endTime; None: prerun_end_time + episode_time (a coupled run restarts
    #: from the pre-run snapshot and preCICE ends it after max-time)
    end_time: float | None = None

    @property
    def episode_time(self) -> float:
        return self.actions_per_episode * self.steps_per_action * self.flow.dt

    @property
    def action_time(self) -> float:
        return self.steps_per_action * self.flow.dt

    @property
    def time_window(self) -> float:
        """The preCICE time window: one solver step, or one action (:attr:`coupling`)."""
        if self.coupling not in ("step", "action"):
            raise ValueError(f"coupling must be 'step' or 'action', got {self.coupling!r}")
        return self.action_time if self.coupling == "action" else self.flow.dt

    @property
    def interfaces(self) -> tuple[str, ...]:
        if self.control == "jets":
            return ("jet1", "jet2")
        return ("cylinder",)


#: The training case of the ``*-fast`` environments: the quick start's coarse mesh (3,580
#: cells) with PISO on one rank at twice the time step, one preCICE time window per action
#: (25 substeps of 1e-3 s), 1 s episodes, and eight start snapshots spread over one
#: shedding period (two held out for evaluation). Half the CPU of the quick start per
#: simulated second; its physics against Schäfer-Turek is in docs/training.md.
FAST_TRAINING = {
    "resolution": Resolution.coarse(),
    "flow": Flow(dt=1e-3, outer_correctors=1),
    "steps_per_action": 25,
    "actions_per_episode": 40,
    "coupling": "action",
    "prerun_end_time": 5.0,
    "snapshots": (4.7, 4.74, 4.78, 4.82, 4.86, 4.9, 4.94, 4.98),
    "n_procs": 1,
}

CASES: dict[str, CaseSpec] = {
    "jet_cylinder": CaseSpec(name="jet_cylinder", control="jets"),
    "rotating_cylinder": CaseSpec(name="rotating_cylinder", control="rotation"),
    "quickstart": CaseSpec(
        name="quickstart",
        control="jets",
        resolution=Resolution.coarse(),
        flow=Flow(outer_correctors=1),
        actions_per_episode=20,
        prerun_end_time=5.0,
        n_procs=1,
    ),
    "jet_cylinder_fast": CaseSpec(name="jet_cylinder_fast", control="jets", **FAST_TRAINING),
    "rotating_cylinder_fast": CaseSpec(
        name="rotating_cylinder_fast", control="rotation", **FAST_TRAINING
    ),
}


def case_spec(name: str, **overrides: object) -> CaseSpec:
    """The packaged spec ``name`` with fields replaced by ``overrides``."""
    try:
        spec = CASES[name]
    except KeyError:
        raise KeyError(f"no case recipe {name!r}; the recipes are {sorted(CASES)}") from None
    return replace(spec, **overrides) if overrides else spec
