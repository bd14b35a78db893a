"""The FSI3 environment: two jets on the cylinder against the bar's swing.

Task: Turek and Hron's FSI3 (:mod:`gymprecice_tutorials.turek_hron`). The flow past the
cylinder sheds vortices and the elastic bar behind it swings; the controller blows and
sucks through two jets on the cylinder (at 90° and 270°, as on the jet cylinder) to
damp the swing without raising the drag.

* **Action** ``(1,)``: the jets' flow rate ``Q`` (m³/s over the mesh's depth), within
  ``±max_flow_rate``; jet 1 blows ``Q`` and jet 2 sucks it, so no net mass enters.
  The default bound is 6 % of the mean inflow's rate, as Rabault et al. bound theirs.
* **Observation** ``(2,)``: the bar tip's displacement ``(dx, dy)`` (m) at the step's
  end, from the solid's preCICE watch point ``Flap-Tip`` (point A of the benchmark).
* **Reward**: ``-(mean |dy| / A_REF) - drag_weight * max(0, drag / DRAG_REF - 1)``, the
  means over the time windows of the step: the swing against the benchmark's (``A_REF``,
  its tip amplitude, 34.38 mm), and a penalty on drag above the benchmark's mean
  (``DRAG_REF``, 457.3 N/m), both from :data:`.reference.PUBLISHED`; drag at or below
  the benchmark's costs nothing. ``drag_weight`` (default 1) weighs the drag against the
  swing (:func:`reward_terms`).
* **Episode end**: truncated at the coupling's max-time; no terminal state.
* **Start**: without ``starts``, every episode starts from the fluid at rest under the
  benchmark's ramped inflow and lasts ``end_time`` seconds. With ``starts`` (a library of
  the swinging state's saved states, :mod:`.starts`), an episode starts from one of them
  and lasts ``episode_time`` seconds: ``reset(options={"split": "eval", "start": k})``
  takes the k-th held-out start, ``"validation"`` those that choose a model, and training
  draws from the rest with the env's seed. Starts need the FEniCS bar (``solid``
  defaults to it then): the deal.II program cannot restart from a saved state. The
  case (``resolution``, ``time_step``, ``degree``) is the library's unless given; one
  that differs is refused. Without starts it is the coarse mesh, 1 ms and degree 2.
* ``uncontrolled=True``: the jets stay shut (zero flow) whatever the action, the
  reference run the lab's baselines compare with.

``info["metrics"]`` holds the tip's displacement (``tip_dx``, ``tip_dy`` at the step's end,
``mean_abs_tip_dy`` over it, m), the drag and lift on the cylinder, its jets and the bar
(N per metre of depth, the benchmark's forces, the means over the step), the reward's
two terms (``swing`` and ``drag_penalty``) and their sum, ``cost`` (the negated reward,
what the lab ranks controllers on). Uncontrolled, the run is the benchmark's:
:mod:`.validate` compares it.

The registered id ``gymprecice/TurekHronFSI3-v0`` is :class:`TurekHronControlEnv`: this
env, its episodes from the library of starts at :func:`.starts.default_starts` unless
``starts=`` names another (``None``: from rest).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from gymprecice.env.core import Adapter
from gymprecice.plugin.fields import Overlay
from gymprecice_openfoam import actuators
from gymprecice_openfoam.outputs import last_per_time
from gymprecice_tutorials.case_files import write_case_files
from gymprecice_tutorials.turek_hron import starts as start_library
from gymprecice_tutorials.turek_hron.case import INFLOW_MEAN, case_files
from gymprecice_tutorials.turek_hron.mesh import GEOMETRY
from gymprecice_tutorials.turek_hron.reference import PUBLISHED

__all__ = [
    "A_REF",
    "DEFAULT_STARTS",
    "DRAG_REF",
    "MAX_FLOW_RATE",
    "START_FILE",
    "TurekHronControlEnv",
    "TurekHronEnv",
    "reward_terms",
]

#: the file the FEniCS solver copies the episode's saved bar state to (its ``start_file``)
START_FILE = "start-state.npz"

#: 6 % of the mean inflow's rate through the channel, over the mesh's depth (m³/s)
MAX_FLOW_RATE = 0.06 * INFLOW_MEAN * GEOMETRY.height * GEOMETRY.depth

#: the reward's scales, the benchmark's: the tip's swing (amplitude of ``dy``, m) and the
#: mean drag on the cylinder and the bar (N per metre of depth)
A_REF = PUBLISHED["tip_dy_amplitude"].value
DRAG_REF = PUBLISHED["drag_mean"].value


def reward_terms(
    mean_abs_dy: float, mean_drag: float, drag_weight: float = 1.0
) -> tuple[float, float]:
    """The reward's two costs, ``(swing, drag_penalty)``: the step's mean ``|dy|`` over
    :data:`A_REF`, and ``drag_weight`` times the step's mean drag's excess over
    :data:`DRAG_REF` as a fraction of it (none at or below it). The reward is minus
    their sum; a NaN drag (no force row) stays NaN, for the env's guards to see."""
    swing = float(mean_abs_dy) / A_REF
    excess = float(np.maximum(0.0, float(mean_drag) / DRAG_REF - 1.0))
    return swing, float(drag_weight) * excess


class TurekHronEnv(Adapter):
    """Jets on the cylinder against the bar's swing (see the module docstring)."""

    SOLID = "solid"
    FLUID = "fluid"
    WATCH_POINT = "Flap-Tip"
    JETS = (("jet1", 90.0, 1.0), ("jet2", 270.0, -1.0))
    metadata: dict[str, Any] = {"render_modes": ["rgb_array"], "render_fps": 25}

    def __init__(
        self,
        options: Mapping[str, Any] | str | Path | None = None,
        idx: int = 0,
        *,
        resolution: str | None = None,
        time_step: float | None = None,
        end_time: float = 8.0,
        degree: int | None = None,
        action_time: float = 0.02,
        solid: str | None = None,
        starts: str | Path | None = None,
        episode_time: float = 1.0,
        max_flow_rate: float = MAX_FLOW_RATE,
        drag_weight: float = 1.0,
        uncontrolled: bool = False,
        watch_timeout: float = 300.0,
        run_root: str | Path | None = None,
        solid_settings: dict[str, Any] | None = None,
        fluid_writes: tuple[float, int] | None = None,
        **kwargs: Any,
    ) -> None:
        if not max_flow_rate > 0:  # before anything is written or started
            raise ValueError(f"max_flow_rate must be positive, got {max_flow_rate}")
        if not (math.isfinite(drag_weight) and drag_weight >= 0):
            raise ValueError(f"drag_weight must be a finite number >= 0, got {drag_weight}")
        solid = solid or ("fenics" if starts is not None else "dealii")
        self.starts = start_library.load(starts) if starts is not None else None
        # the case: the library's by default, else the validated coarse run's
        if self.starts is not None:
            resolution = resolution or self.starts.resolution
            time_step = time_step or self.starts.time_step
            degree = degree or self.starts.degree
        resolution, time_step, degree = resolution or "coarse", time_step or 1e-3, degree or 2
        if options is None:
            if self.starts is not None:
                files = self._files_from_starts(
                    self.starts,
                    resolution,
                    time_step,
                    episode_time,
                    degree,
                    action_time,
                    solid,
                    solid_settings,
                    fluid_writes,
                )
                name = f"turek-hron-fsi3-{resolution}-starts"
            else:
                files = case_files(
                    resolution,
                    time_step,
                    end_time,
                    degree,
                    action_time,
                    solid,
                    solid_settings,
                    fluid_writes,
                )
                name = f"turek-hron-fsi3-{resolution}" + ("" if solid == "dealii" else f"-{solid}")
            options = write_case_files(name, files, run_root)
        super().__init__(options, idx, run_root=run_root, **kwargs)
        self.max_flow_rate = float(max_flow_rate)
        self.drag_weight = float(drag_weight)
        self.uncontrolled = bool(uncontrolled)
        self.watch_timeout = float(watch_timeout)
        bound = np.float32(self.max_flow_rate)
        self.action_space = gym.spaces.Box(-bound, bound, shape=(1,), dtype=np.float32)
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, shape=(2,), dtype=np.float32)
        self._tip: Any = None
        self._forces: Any = None
        self._step_rows = np.zeros((0, 0))
        #: the step's mean |dy|, drag and lift, read once by _get_reward for step's metrics
        self._step_means: tuple[float, float, float] = (math.nan, math.nan, math.nan)

    @staticmethod
    def _files_from_starts(
        library: start_library.StartLibrary,
        resolution: str,
        time_step: float,
        episode_time: float,
        degree: int,
        action_time: float,
        solid: str,
        solid_settings: dict[str, Any] | None = None,
        fluid_writes: tuple[float, int] | None = None,
    ) -> dict[str, str]:
        """The case of episodes from the library's starts: the packaged case run for
        ``episode_time`` from each start, the fluid's time directories in it as snapshots
        and the bar's states as the FEniCS solver's starts, in the same split
        (``solid_settings`` and ``fluid_writes`` as :func:`~.case.case_files` takes them)."""
        if solid != "fenics":
            raise ValueError(
                f"starts need solid='fenics' (the FEniCS bar restarts from a saved state; "
                f"the deal.II program cannot), got solid={solid!r}"
            )
        library.check(resolution, time_step, degree)
        settings = {**(solid_settings or {}), "start_state": START_FILE}
        files = case_files(
            resolution, time_step, episode_time, degree, action_time, solid, settings, fluid_writes
        )
        files.update(library.fluid_files())
        # Both sides of the bar start from the saved state: the fluid's first iteration
        # reads the bar's displacement (its mesh already deformed) and the bar the fluid's
        # stress, rather than zeros that pull the mesh back to the bar at rest.
        xml = files["precice-config.xml"]
        for exchange in (
            '<exchange data="Stress" mesh="Fluid-Mesh-Centres" from="Fluid" to="Solid"',
            '<exchange data="Displacement" mesh="Solid-Mesh" from="Solid" to="Fluid"',
        ):
            if xml.count(exchange + " />") != 1:
                raise ValueError(
                    f"the packaged precice-config.xml has no single {exchange!r}; update "
                    "TurekHronEnv._files_from_starts to the packaged case"
                )
            xml = xml.replace(exchange + " />", exchange + ' initialize="true" />')
        # No relaxation of the first iterate: preCICE stores the "previous iterate" that its
        # first relaxation blends with before the initial data is exchanged, so with the
        # packaged 0.1 the fluid's first mesh would be a tenth of the saved displacement,
        # the bar thrown back towards rest (a start with the tip 25 mm off diverged in its
        # first window). From a saved state the first iterate is already the saved motion
        # continued; from rest both are zero and the packaged value stays.
        relaxation = '<initial-relaxation value="0.1" />'
        if xml.count(relaxation) != 1:
            raise ValueError(
                f"the packaged precice-config.xml has no single {relaxation!r}; update "
                "TurekHronEnv._files_from_starts to the packaged case"
            )
        xml = xml.replace(relaxation, '<initial-relaxation value="1" />')
        files["precice-config.xml"] = xml
        config = json.loads(files["gymprecice-config.json"])
        solvers = config["physics_simulation_engine"]["solvers"]
        solvers[TurekHronEnv.FLUID]["options"]["snapshots"] = {
            split: [float(name) for name in names] for split, names in library.split.items()
        }
        solvers[TurekHronEnv.SOLID]["options"].update(
            starts={
                split: [str(library.solid_state(name)) for name in names]
                for split, names in library.split.items()
            },
            start_file=START_FILE,
        )
        files["gymprecice-config.json"] = json.dumps(config, indent=4) + "\n"
        return files

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Core's reset; with starts, the episode's start is chosen here, from the env's
        seed, and both solvers are given it, so the fluid and the bar start together."""
        if self.starts is None:
            return super().reset(seed=seed, options=options)
        gym.Env.reset(self, seed=seed)  # seeds np_random before the draw
        options = dict(options or {})
        split = options.get("split") or "train"
        pool = self.starts.times if split == "all" else self.starts.split.get(split)
        if not pool:
            raise ValueError(
                f"reset option split={split!r}: the starts in {self.starts.path} have "
                f"splits {sorted(self.starts.split)} (or 'all')"
            )
        start = options.get("start")
        if start is None:
            start = int(self.np_random.integers(len(pool)))
        if isinstance(start, bool) or not isinstance(start, (int, np.integer)):
            raise ValueError(f"reset option start={start!r}: must be an integer index")
        if not 0 <= start < len(pool):
            raise ValueError(
                f"reset option start={start}: split {split!r} has {len(pool)} start(s) "
                f"({', '.join(pool)}); use 0 to {len(pool) - 1}"
            )
        name = pool[int(start)]
        # Each solver is told the start by its own split and index: "all" is not in the
        # same order for both (the fluid sorts its snapshots by time, the bar's files
        # keep the splits' order), so a start of "all" goes as the split that holds it.
        own = next(s for s, names in self.starts.split.items() if name in names)
        chosen = {"split": own, "start": self.starts.split[own].index(name)}
        obs, info = super().reset(seed=None, options={**options, **chosen})
        return obs, {**info, "start": {"split": split, "index": int(start), "time": name}}

    @property
    def held_out_starts(self) -> tuple[str, ...]:
        """The held-out starts, in the order ``reset(options={"split": "eval", "start":
        k})`` takes them (none without a library of starts)."""
        return self._labels("eval")

    @property
    def validation_starts(self) -> tuple[str, ...]:
        """The starts that choose a model, as ``"split": "validation"`` takes them."""
        return self._labels("validation")

    def _labels(self, split: str) -> tuple[str, ...]:
        if self.starts is None:
            return ()
        return tuple(f"t = {name} s" for name in self.starts.split.get(split, []))

    @property
    def render_fields(self) -> dict[str, tuple[str, ...]]:  # type: ignore[override]
        """The fluid's speed and the bar's displacement, drawn on the bent bar."""
        return {self.FLUID: ("U",), self.SOLID: ("displacement",)}

    def _render_overlay(self) -> Overlay:
        q = self.flow_rate(self.last_action)
        return Overlay(text=[f"jet flow rate {q:+.2e} m³/s"])

    # -- the four user methods -------------------------------------------------------------
    def _get_action(self, action: Any, write_var_list: list) -> dict:
        q = self.flow_rate(action)
        centre = (*GEOMETRY.centre, 0.0)
        width = math.radians(GEOMETRY.jet_width)
        return {
            name: actuators.jet_velocity(
                self.interface_geometry[name],
                sign * q,
                centre=centre,
                width=width,
                jet_angle=math.radians(angle),
                direction="radial",
            )
            for name, angle, sign in self.JETS
        }

    def _get_observation(self, read_data: Any, read_var_list: list) -> np.ndarray:
        if self._tip is None:  # core closes readers at every reset: open one per episode
            self._tip = self.open_output(self.SOLID, "watchpoint", point=self.WATCH_POINT)
        self._step_rows = self._tip.wait_until(self.time, self.watch_timeout)
        displacement = self._tip.field("Displacement", self._tip.data[-1:])[0]
        return np.asarray(displacement, dtype=np.float32)

    def _get_reward(self) -> float:
        rows = self._step_rows if len(self._step_rows) else self._tip.data[-1:]
        mean_abs_dy = float(np.mean(np.abs(self._tip.field("Displacement", rows)[:, 1])))
        drag, lift = self.forces()
        self._step_means = (mean_abs_dy, drag, lift)
        swing, drag_penalty = reward_terms(mean_abs_dy, drag, self.drag_weight)
        return -(swing + drag_penalty)

    def _close_external_resources(self) -> None:
        self._tip = None
        self._forces = None
        self._step_rows = np.zeros((0, 0))
        self._step_means = (math.nan, math.nan, math.nan)

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Core's step, plus the tip's displacement, the forces and the reward's terms in
        ``info["metrics"]``."""
        obs, reward, terminated, truncated, info = super().step(action)
        info["action"] = [self.flow_rate(action)]
        if "diverged" in info:  # the penalty's step: no new tip or force rows were read
            return obs, reward, terminated, truncated, info
        mean_abs_dy, drag, lift = self._step_means
        swing, drag_penalty = reward_terms(mean_abs_dy, drag, self.drag_weight)
        info["metrics"] = {
            "tip_dx": float(obs[0]),
            "tip_dy": float(obs[1]),
            "mean_abs_tip_dy": mean_abs_dy,
            "drag": drag,
            "lift": lift,
            "swing": swing,
            "drag_penalty": drag_penalty,
            "cost": swing + drag_penalty,
        }
        return obs, reward, terminated, truncated, info

    # -- helpers ---------------------------------------------------------------------------
    def forces(self) -> tuple[float, float]:
        """Drag and lift (N per metre of depth) on the cylinder, its jets and the bar,
        the means over the time windows of the step that just ended."""
        if self._forces is None:
            self._forces = self.open_output(self.FLUID, "forces", type="forces")
        # The reader speaks the fluid's clock, which an episode from a start begins at the
        # start's time (the plugin opens it there); coupling time begins at 0.
        offset = float(getattr(self._forces, "start_time", None) or 0.0)
        # implicit coupling writes a row per coupling iteration: the converged one is last
        rows = last_per_time(self._forces.wait_until(offset + self.time, self.watch_timeout))
        if not len(rows):
            return math.nan, math.nan
        drag = float(np.mean(rows.column("total_x"))) / GEOMETRY.depth
        lift = float(np.mean(rows.column("total_y"))) / GEOMETRY.depth
        return drag, lift

    def _initial_action(self) -> np.ndarray:
        return np.zeros(1, dtype=np.float32)

    def flow_rate(self, action: Any) -> float:
        """The jets' flow rate an action asks for, clipped to the action space; 0 (the
        jets shut) whatever the action where the env is ``uncontrolled``."""
        if self.uncontrolled:
            return 0.0
        value = float(np.asarray(action, dtype=float).reshape(-1)[0])
        return float(np.clip(value, -self.max_flow_rate, self.max_flow_rate))


class _DefaultStarts:
    """The registered env's ``starts`` default: the library at :func:`.starts.default_starts`."""

    def __repr__(self) -> str:
        return "<the library at gymprecice_tutorials.turek_hron.starts.default_starts()>"


DEFAULT_STARTS: Any = _DefaultStarts()


class TurekHronControlEnv(TurekHronEnv):
    """``gymprecice/TurekHronFSI3-v0``: :class:`TurekHronEnv` with its episodes from the
    library of starts at :func:`.starts.default_starts` unless ``starts=`` names another
    (``None``: from rest, as :class:`TurekHronEnv` by default).

    A missing default library is refused here, when the env is made, naming its folder
    and the command that builds it: the build is one long uncontrolled run.
    """

    def __init__(
        self,
        options: Mapping[str, Any] | str | Path | None = None,
        idx: int = 0,
        *,
        starts: str | Path | None = DEFAULT_STARTS,
        **kwargs: Any,
    ) -> None:
        if starts is DEFAULT_STARTS:
            starts = start_library.default_starts()
            if not (starts / start_library.INDEX).is_file():
                raise FileNotFoundError(
                    f"gymprecice/TurekHronFSI3-v0 starts its episodes from a library of FSI3's "
                    f"swinging state, and there is none in {starts}. Build it there with "
                    f"`{start_library.BUILD_COMMAND}` (one uncontrolled coupled run, "
                    f"{start_library.BUILD_COST}; the same command goes on after an "
                    "interruption), or pass starts=DIR to use a library built elsewhere "
                    f"(`{start_library.BUILD_COMMAND} --out DIR`)."
                )
        super().__init__(options, idx, starts=starts, **kwargs)
