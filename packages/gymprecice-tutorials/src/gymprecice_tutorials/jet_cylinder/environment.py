"""JetCylinder-v0: drag reduction behind a cylinder with two synthetic jets (Rabault et al. 2019).

The flow is the Schäfer-Turek 2D-2 benchmark (Re = 100, pimpleFoam, dt = 5e-4 s) with two
jets on the cylinder at 90° and 270°. An action is one jet flow rate ``Q``; jet 1 blows
``Q`` and jet 2 sucks ``Q`` so that no net mass enters the channel. One action lasts 50
solver steps (0.025 s), ramped from the previous one by core's action schedule, and an
episode is 80 actions (2 s, about six shedding periods) from a developed-shedding snapshot.

* observation: the 151 pressure probes of Rabault et al. at the end of the action;
* reward: ``reward_offset - <Cd> - lift_penalty * |<Cl>|``, the means taken over the last
  ``averaging_window`` seconds (one shedding period): averaging over a whole period makes
  the reward measure the mean drag rather than where in the shedding cycle the action
  ended, and the lift term stops the agent from buying drag with a steady side force.

:class:`CylinderFlowEnv` holds what the jet, the rotating and the quickstart cylinders share:
the case (a packaged recipe materialised on demand, or a directory of one's own), the
probe observation and the force-coefficient reward, all read from OpenFOAM's
function-object files through the OpenFOAM plugin's output readers.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np

from gymprecice.env.core import Adapter, DataRef
from gymprecice.plugin.fields import Overlay
from gymprecice.plugin.solver import InterfaceGeometry, OutputReader
from gymprecice_openfoam import actuators
from gymprecice_tutorials import recipes
from gymprecice_tutorials.case_files import write_case_files
from gymprecice_tutorials.cylinder_geometry import patch_geometry
from gymprecice_tutorials.recipes import CaseSpec

__all__ = [
    "CylinderFlowEnv",
    "JetCylinderEnv",
    "materialise_case",
]

#: Largest jet flow rate (m³/s). Rabault et al. bound |Q| by 6 % of the inflow rate
#: Umean * H = 1.0 * 0.41 m²/s per unit depth; the 2-D mesh is ``depth`` = 0.01 m deep, so
#: 0.06 * 0.41 * 0.01 = 2.46e-4, rounded to 2.5e-4 (the value of the Gym-preCICE tutorial).
MAX_FLOW_RATE = 2.5e-4
#: Mean drag coefficient of the uncontrolled flow at Re = 100 (Rabault et al.): a reward
#: offset that makes "no control" score about zero, so the return reads as drag saved.
REWARD_OFFSET = 3.205
#: Weight of |<Cl>| in the reward (Rabault et al.).
LIFT_PENALTY = 0.2
#: One vortex-shedding period at St ~ 0.3 (f = St * Umean / D ~ 2.98 Hz).
SHEDDING_PERIOD = 0.335
#: Seconds an observation may wait for the solver to write the step's output.
OUTPUT_TIMEOUT = 120.0


def materialise_case(
    spec: CaseSpec, root: str | Path | None = None, *, double: bool = False, **double_options: Any
) -> Path:
    """Write the case of ``spec`` once under ``<root>/cases/`` and return its directory.

    See :func:`gymprecice_tutorials.case_files.write_case_files` for the naming and the
    lock-free writing. ``double=True`` writes the test-double variant
    (:func:`gymprecice_tutorials.fake_flow.double_case_files`).
    """
    if double:
        from gymprecice_tutorials import fake_flow

        files = fake_flow.double_case_files(spec, **double_options)
    else:
        files = recipes.case_files(spec)
    return write_case_files(f"{spec.name}{'-double' if double else ''}", files, root)


class CylinderFlowEnv(Adapter):
    """Shared base: a Schäfer-Turek cylinder case observed by probes, rewarded by forces.

    Subclasses set ``recipe`` (the packaged case recipe), the action space, and
    ``_get_action``. See :class:`JetCylinderEnv` for the keyword arguments.
    """

    #: ``render_mode="rgb_array"``: the fluid's speed, one frame per action (0.025 s)
    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["rgb_array"], "render_fps": 20}
    render_fields: ClassVar[dict[str, str]] = {"fluid": "U"}
    recipe: ClassVar[str] = "jet_cylinder"
    #: the fluid solver in gymprecice-config.json (the recipes call it "fluid")
    fluid: ClassVar[str] = "fluid"

    def __init__(
        self,
        options: Mapping[str, Any] | str | Path | None = None,
        idx: int = 0,
        *,
        case_dir: str | Path | None = None,
        run_root: str | Path | None = None,
        double: bool = False,
        reward_offset: float = REWARD_OFFSET,
        lift_penalty: float = LIFT_PENALTY,
        averaging_window: float = SHEDDING_PERIOD,
        lift_measure: str = "mean",
        episode_time: float | None = None,
        output_timeout: float = OUTPUT_TIMEOUT,
        case_overrides: Mapping[str, Any] | None = None,
        double_options: Mapping[str, Any] | None = None,
        render_mode: str | None = None,
    ) -> None:
        if averaging_window <= 0:
            raise ValueError(f"averaging_window must be positive, got {averaging_window}")
        if lift_measure not in ("mean", "abs"):
            raise ValueError(f"lift_measure must be 'mean' or 'abs', got {lift_measure!r}")
        self.case_spec = self._make_spec(episode_time, dict(case_overrides or {}))
        if options is None and case_dir is None:
            options = materialise_case(
                self.case_spec, run_root, double=double, **dict(double_options or {})
            )
        else:
            if double or episode_time is not None or case_overrides or double_options:
                raise ValueError(
                    "double, double_options, episode_time and case_overrides shape the "
                    "packaged case recipe; with a case of your own (options or case_dir) "
                    "change the case itself instead"
                )
            if options is None:
                options, case_dir = case_dir, None
        super().__init__(
            options, idx, run_root=run_root, case_dir=case_dir, render_mode=render_mode
        )
        self.reward_offset = float(reward_offset)
        self.lift_penalty = float(lift_penalty)
        self.averaging_window = float(averaging_window)
        self.lift_measure = lift_measure
        self.output_timeout = float(output_timeout)
        self.n_probes = len(recipes.probe_locations(self.case_spec.geometry))
        self.observation_space = gym.spaces.Box(
            -np.inf, np.inf, shape=(self.n_probes,), dtype=np.float32
        )
        if self.config.solvers[self.fluid].kind != "openfoam":
            # A stand-in solver (the test double's scripted flow) has no mesh a plugin could
            # read: give the controller the recipe's patch geometry.
            for name, geometry in self._analytic_geometry().items():
                self.set_interface_vertices(name, geometry.coordinates)
            self._fallback_geometry = self._analytic_geometry()
        else:
            self._fallback_geometry = {}
        self._probes: OutputReader | None = None
        self._coeffs: OutputReader | None = None
        self._history = np.zeros((0, 3))  # rows (time, Cd, Cl) within the averaging window
        self._new_coeffs = np.zeros((0, 3))
        self._last_probes = np.zeros(self.n_probes, dtype=np.float32)
        self._metrics: dict[str, float] = {}

    # -- the case ----------------------------------------------------------------------------
    def _make_spec(self, episode_time: float | None, overrides: dict[str, Any]) -> CaseSpec:
        # ``--env-kwargs`` is JSON: a mapping for ``geometry``, ``resolution`` or ``flow``
        # replaces only the fields it names, e.g. {"flow": {"dt": 1e-3}}
        base = recipes.case_spec(self.recipe)
        for name in ("geometry", "resolution", "flow"):
            if isinstance(overrides.get(name), Mapping):
                overrides[name] = replace(getattr(base, name), **overrides[name])
        if "snapshots" in overrides:
            overrides["snapshots"] = tuple(float(t) for t in overrides["snapshots"])
        spec = recipes.case_spec(self.recipe, **overrides) if overrides else None
        spec = spec or recipes.case_spec(self.recipe)
        if episode_time is not None:
            per_action = spec.steps_per_action * spec.flow.dt
            actions = max(1, round(float(episode_time) / per_action))
            spec = replace(spec, actions_per_episode=actions)
        return spec

    def _analytic_geometry(self) -> dict[str, InterfaceGeometry]:
        """Geometry of this env's interfaces on the recipe mesh (see :mod:`.geometry`)."""
        raise NotImplementedError

    def geometry_of(self, interface: str) -> InterfaceGeometry:
        """The interface geometry, with normals/areas from the recipe where none were read."""
        geometry = self.interface_geometry[interface]
        if (geometry.normals is None or geometry.areas is None) and (
            interface in self._fallback_geometry
        ):
            fallback = self._fallback_geometry[interface]
            if len(fallback.coordinates) == len(geometry.coordinates):
                return InterfaceGeometry(
                    geometry.coordinates, fallback.normals, fallback.areas, geometry.patches
                )
        return geometry

    @property
    def held_out_starts(self) -> tuple[str, ...]:
        """The starts kept out of training, in the order ``reset(options={"split": "eval",
        "start": k})`` takes them (empty: the case has no snapshot library).

        An OpenFOAM case's are its ``snapshots`` option's eval split (the OpenFOAM plugin's
        rule). The test double's flow has no snapshots: it names the recipe's held-out
        snapshots, but starts every episode from the same state.
        """
        return self._snapshot_starts("eval")

    @property
    def validation_starts(self) -> tuple[str, ...]:
        """The starts that choose the model a training run keeps, in the order
        ``reset(options={"split": "validation", "start": k})`` takes them: the snapshot
        library's validation split (empty: the case keeps none). On the test double, as
        :attr:`held_out_starts`: names only."""
        return self._snapshot_starts("validation")

    def _snapshot_starts(self, split: str) -> tuple[str, ...]:
        """Labels of the snapshot library's ``split``, in time order."""
        from gymprecice_openfoam.case import split_snapshots

        solver = self.config.solvers[self.fluid]
        if solver.kind == "openfoam":
            raw = solver.options.get("snapshots") or []
            if isinstance(raw, Mapping):
                times = [float(t) for t in raw.get(split, [])]
            else:
                names = [f"{float(t):g}" for t in raw]
                parts = split_snapshots(names, dict(solver.options)) if names else {}
                times = [float(t) for t in parts.get(split, [])]
        else:
            names = [f"{t:g}" for t in self.case_spec.snapshots]
            parts = split_snapshots(names, {"validation_fraction": 0.25}) if names else {}
            times = [float(t) for t in parts.get(split, [])]
        return tuple(f"t = {t:g} s" for t in sorted(times))

    # -- reading the solver's outputs ------------------------------------------------------
    def _open(self) -> tuple[OutputReader, OutputReader]:
        """The OpenFOAM plugin's readers of the fluid's probes and force coefficients.

        They read OpenFOAM's function-object files, whoever writes them: OpenFOAM, or the
        test double's fake flow. Core closes them at every reset.
        """
        if self._probes is None:
            self._probes = self.open_output(self.fluid, "probes", field="p")
        if self._coeffs is None:
            self._coeffs = self.open_output(self.fluid, "forceCoeffs")
        return self._probes, self._coeffs

    @staticmethod
    def _offset(reader: OutputReader) -> float:
        """Solver time at the episode's start (the readers speak the solver's clock).

        A restart from the pre-run snapshot makes OpenFOAM's time run from that snapshot
        (e.g. 8 s) while coupling time starts at 0; the plugin opens readers with the
        episode's ``start_time``.
        """
        return float(getattr(reader, "start_time", None) or 0.0)

    def _solver_time(self, reader: OutputReader) -> float:
        return self._offset(reader) + self.time

    def _read_probes(self) -> np.ndarray:
        probes, _ = self._open()
        if self.time <= 0.0:
            # OpenFOAM writes probes after each time step, not at the start: the reset
            # observation is the snapshot's row when the solver wrote one, else zeros.
            rows = probes.read_new()
        else:
            rows = probes.wait_until(self._solver_time(probes), self.output_timeout)
        if len(rows):
            values = np.asarray(rows.values[-1], dtype=np.float32).reshape(-1)
            if values.shape != (self.n_probes,):
                raise ValueError(
                    f"the probes output has {values.size} values per row, the observation "
                    f"needs {self.n_probes}; the case's system/probes must list the "
                    f"{self.n_probes} probes of the recipe"
                )
            self._last_probes = values
        elif self.time <= 0.0:
            self._last_probes = np.zeros(self.n_probes, dtype=np.float32)
        return self._last_probes.copy()

    def _read_coefficients(self) -> None:
        _, coeffs = self._open()
        if self.time <= 0.0:
            rows = coeffs.read_new()
        else:
            rows = coeffs.wait_until(self._solver_time(coeffs), self.output_timeout)
        if len(rows):
            new = np.column_stack(
                [rows.time - self._offset(coeffs), rows.column("Cd"), rows.column("Cl")]
            )
        else:
            new = np.zeros((0, 3))
        self._new_coeffs = new
        history = np.concatenate([self._history, new])
        # rows in (t - window, t]: a window of w seconds holds w / dt solver steps
        keep = history[:, 0] > self.time - self.averaging_window + 1e-9 * max(1.0, self.time)
        self._history = history[keep]

    # -- the user API ----------------------------------------------------------------------
    def _get_observation(self, read_data: Any, read_var_list: list[DataRef]) -> np.ndarray:
        obs = self._read_probes()
        self._read_coefficients()
        return obs

    def _get_reward(self) -> float:
        if not len(self._history):
            raise RuntimeError(
                f"no force coefficients were written between t={self.time - self.averaging_window:g}"
                f" and t={self.time:g}; the case's forceCoeffs function object must write "
                "every time step"
            )
        cd = float(self._history[:, 1].mean())
        cl = float(self._history[:, 2].mean())
        self._metrics = {"Cd": cd, "Cl": cl}
        # "mean": |<Cl>|, blind to a lift that swings about zero within the window;
        # "abs": <|Cl|>, the instantaneous lift magnitude that the evaluation reports
        lift = abs(cl) if self.lift_measure == "mean" else float(np.abs(self._history[:, 2]).mean())
        return self.reward_offset - cd - self.lift_penalty * lift

    def _close_external_resources(self) -> None:
        # Core closes the readers it handed out; forget them so the next episode opens new
        # ones on the new run's files.
        self._probes = None
        self._coeffs = None
        self._history = np.zeros((0, 3))
        self._new_coeffs = np.zeros((0, 3))
        self._metrics = {}

    def _clip(self, action: Any) -> np.ndarray:
        """The action as applied: clipped into the action space, as a flat float array.

        A flow rate or spin far outside what the case was meant for can make the CFD
        diverge; PPO's Gaussian samples are clipped by SB3, but direct callers are not.
        """
        space = self.action_space
        values = np.asarray(action, dtype=float).reshape(-1)
        if isinstance(space, gym.spaces.Box):
            values = np.clip(values, space.low.reshape(-1), space.high.reshape(-1))
        return values

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Core's step, plus the step's mean Cd/Cl and its new coefficient rows in ``info``.

        ``info["Cd"]`` / ``info["Cl"]`` are the averages the reward used (also in
        ``info["metrics"]``, the named scalars that evaluation records);
        ``info["coefficients"]`` holds the rows ``(time, Cd, Cl)`` the solver wrote during
        this step (what evaluation and plots draw as time series).
        """
        obs, reward, terminated, truncated, info = super().step(action)
        info.update(self._metrics)
        info["metrics"] = dict(self._metrics)
        info["action"] = self._clip(action).tolist()
        info["coefficients"] = self._new_coeffs.copy()
        return obs, reward, terminated, truncated, info


class JetCylinderEnv(CylinderFlowEnv):
    """Two zero-net-mass-flux jets on the cylinder; the action is the jet flow rate (m³/s).

    Keyword arguments (all optional):

    * ``options`` / ``case_dir``: a gymprecice case of one's own (``options``: the
      configuration or its path; ``case_dir``: a case directory). Default: the packaged
      recipe written under ``<run_root>/cases/``.
    * ``idx``: the env's index (its run directory is ``<run_root>/env_<idx>``).
    * ``run_root``: where run directories (and materialised cases) go; default
      ``gymprecice-runs`` in the working directory.
    * ``double``: run against gymprecice's preCICE test double and the scripted fake flow
      of :mod:`gymprecice_tutorials.fake_flow` (no preCICE, no OpenFOAM needed).
    * ``max_flow_rate``: the bound ``Qmax`` of the action space (see :data:`MAX_FLOW_RATE`).
    * ``jet_width``: angular width of each jet in degrees (changes the recipe's mesh).
    * ``reward_offset``, ``lift_penalty``, ``averaging_window``: the reward's constants.
    * ``lift_measure``: ``"mean"`` (default) penalises ``|<Cl>|``, the magnitude of the
      window's mean lift; ``"abs"`` penalises ``<|Cl|>``, which also sees a lift that swings
      about zero (the bang-bang forcing PPO otherwise finds).
    * ``episode_time``: simulated seconds per episode (default: the recipe's 2 s); a
      multiple of one action's 0.025 s.
    * ``output_timeout``: seconds to wait for the solver's probe/force output of a step.
    * ``case_overrides``: other :class:`~gymprecice_tutorials.recipes.CaseSpec` fields
      (``geometry``, ``resolution`` and ``flow`` as mappings of the fields to change), e.g.
      ``{"coupling": "action"}``: one preCICE time window per action, the solver subcycling
      inside it (see :attr:`~gymprecice_tutorials.recipes.CaseSpec.coupling`).
    * ``double_options``: options of the test-double case (see ``fake_flow``).
    """

    recipe: ClassVar[str] = "jet_cylinder"
    interfaces: ClassVar[tuple[str, str]] = ("jet1", "jet2")

    def __init__(
        self,
        options: Mapping[str, Any] | str | Path | None = None,
        idx: int = 0,
        *,
        max_flow_rate: float = MAX_FLOW_RATE,
        jet_width: float | None = None,
        **kwargs: Any,
    ) -> None:
        if max_flow_rate <= 0:
            raise ValueError(f"max_flow_rate must be positive, got {max_flow_rate}")
        if jet_width is not None:
            overrides = dict(kwargs.pop("case_overrides", None) or {})
            base = overrides.get("geometry") or recipes.case_spec(self.recipe).geometry
            overrides["geometry"] = replace(base, jet_width=float(jet_width))
            kwargs["case_overrides"] = overrides
        super().__init__(options, idx, **kwargs)
        self.max_flow_rate = float(max_flow_rate)
        self.jet_width = self.case_spec.geometry.jet_width
        self.action_space = gym.spaces.Box(
            -self.max_flow_rate, self.max_flow_rate, shape=(1,), dtype=np.float32
        )

    def _analytic_geometry(self) -> dict[str, InterfaceGeometry]:
        return {name: patch_geometry(self.case_spec, name) for name in ("jet1", "jet2")}

    def _render_overlay(self) -> Overlay:
        """The jets' flow rate, as text and as arrows out of (or into) the cylinder."""
        q = float(np.asarray(self.last_action, dtype=float).ravel()[0])
        g = self.case_spec.geometry
        (cx, cy), r = g.centre, g.radius
        length = 1.5 * g.diameter * q / self.max_flow_rate
        arrows = [(cx, cy + r, 0.0, length), (cx, cy - r, 0.0, length)]  # blow up, suck up
        return Overlay(
            text=[f"jet 1 Q = {q:+.3e} m³/s", f"jet 2 Q = {-q:+.3e} m³/s"], arrows=arrows
        )

    def _get_action(self, action: Any, write_var_list: list[DataRef]) -> dict[str, np.ndarray]:
        # Rabault et al.: jet 1 blows what jet 2 sucks (no net mass), radially, with a
        # cosine profile over the jet's width; the actuator scales it to carry exactly Q.
        q = float(self._clip(action)[0])
        g = self.case_spec.geometry
        centre = (g.centre[0], g.centre[1], 0.0)
        width = math.radians(g.jet_width)
        return {
            name: actuators.jet_velocity(
                self.geometry_of(name),
                rate,
                centre=centre,
                width=width,
                jet_angle=math.radians(angle),
                direction="radial",
            )
            for name, angle, rate in (("jet1", 90.0, q), ("jet2", 270.0, -q))
        }
