"""PerpendicularFlapFast-v0: damp the flap's swing, the flap's training case.

Why this task needs feedback
----------------------------
The flap (0.1 x 1, E = 4 MPa, rho = 3000 kg/m³) bends with a period of about 1.6 s and
the fluid (nu = 1 m²/s) barely damps it: after the inflow starts, the tip swings by
±0.06 m for seconds, whatever the jet does. A constant jet moves only the centre of the
swing (from dx = 0.07 m with the jet on the flap to 0.01 m with the jet at the top), and a
sinusoid is in phase with the swing only by chance. Lowering the mean tip displacement
below what the best constant jet gives means taking energy out of the swing: pushing
while the tip moves upstream and easing off while it moves downstream, which needs the
tip's state. The objective is :class:`PerpendicularFlapEnv`'s own, the mean magnitude of
the tip displacement.

What a start is
---------------
Fluid and solid run from rest at t = 0, coupled from the first window, so they never
disagree. Each ``reset()`` then drives the coupled case for ``settle_time`` seconds (not
part of the episode) with a *gust*: the jet held at one height and then moved to another
at a random instant. The episode begins at ``settle_time`` with the flap swinging at an
amplitude and phase that the gust set. Training draws its gusts from the episode seed;
``reset(options={"split": "eval"})`` (what ``gymprecice evaluate``, ``baseline``,
``open-loop`` and ``sweep`` ask for) takes the held-out gusts of :data:`EVAL_GUSTS`,
``seed % 3``, which no training draw reproduces (training draws its heights on a grid of
0.05 m offset from theirs by half a step, see :func:`gust`).

The training case
-----------------
The packaged case with these edits (each measured, docs/training.md "The flap"):

* fluid mesh 944 cells instead of 3,780 (half the cells in each direction);
* preCICE time window 0.05 s instead of 0.01 s (fluid time step 0.025 s, the solid's
  step is the window); two windows per action, so 10 actions per second as before;
* solid elements of degree 2 instead of 4 (the deal.II solid; the FEniCS solid keeps its
  quadratic elements on the coupling vertices of degree 2, see ``solid.py``);
* the coupling's max-time: ``settle_time + episode_time``.

The solid is the deal.II one or, with ``solid="fenics"``, preCICE's FEniCS flap, as for
PerpendicularFlap-v0: the policy shipped for this case was trained on the deal.II solid
and is evaluated on both (docs/tutorials/perpendicular-flap.md).

One 4 s run (1 s gust, 3 s episode) costs about 12 s of wall-clock on one core of the
two, against about 80 s for the packaged case.

Two routes to the tip's state
-----------------------------
``observe="watchpoint"`` (the default, what the shipped policy was trained on) reads the
solid's preCICE watch point, a log file the deal.II solver writes at the end of every
window. ``observe="precice"`` asks preCICE itself, the route for any solver that writes no
files: the case then gives the controller one-vertex meshes at the tip
(``Controller-Mesh-tip``, ``Controller-Mesh-force``), onto which preCICE maps the solid's
``Displacement`` and the fluid's ``Force`` (nearest neighbour), exchanged in two more explicit schemes that preCICE
runs once the fluid-solid iterations of a window have converged
(``training_case.PRECICE_OBSERVATION_EDITS``). Both routes give the converged state of the same
window; their cost and their values side by side: ``benchmarks/bench_flap_observation_routes.py``
and docs/training.md. The reward, the task's objective, reads the watch point in both.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from gymprecice_tutorials.case_files import write_case_files
from gymprecice_tutorials.episodes import episode_timing, fixed_start, read_split
from gymprecice_tutorials.perpendicular_flap import double as flap_double
from gymprecice_tutorials.perpendicular_flap.environment import (
    INLET_HEIGHT,
    TIP_HISTORY,
    PerpendicularFlapEnv,
    jet_profile,
)
from gymprecice_tutorials.perpendicular_flap.packaged_case import check_solid
from gymprecice_tutorials.perpendicular_flap.training_case import (
    ACTION_TIME,
    FAST_EDITS,
    PRECICE_OBSERVATION_EDITS,
    TIP,
    WINDOW,
    fast_case_files,
)

__all__ = [
    "EVAL_GUSTS",
    "FAST_EDITS",
    "VALIDATION_GUSTS",
    "PRECICE_OBSERVATION_EDITS",
    "PerpendicularFlapFastEnv",
    "Gust",
    "fast_case_files",
    "gust",
]

#: grid of gust heights (m): training draws ``GUST_STEP * (k + 0.5)``, evaluation uses
#: multiples of ``GUST_STEP``, so the two never share a height
GUST_STEP = 0.05


class Gust(tuple):
    """A start: the jet at ``first`` until ``switch`` seconds, then at ``second``."""

    __slots__ = ()

    def __new__(cls, first: float, second: float, switch: float) -> Gust:
        return super().__new__(cls, (float(first), float(second), float(switch)))

    first = property(lambda self: self[0])
    second = property(lambda self: self[1])
    switch = property(lambda self: self[2])

    def centre(self, time: float) -> float:
        """The jet centre the gust asks for at ``time`` (seconds since the run began)."""
        return self.first if time < self.switch else self.second


#: The held-out starts: the jet on the flap then at the top (a large swing), at the top
#: then on the flap, and a small move in the middle (a small swing of another phase).
EVAL_GUSTS: tuple[Gust, ...] = (
    Gust(1.0, 3.0, 0.5),
    Gust(3.0, 1.0, 0.3),
    Gust(2.0, 1.5, 0.7),
)

#: The validation starts, which choose the model a training run keeps: whole-step heights
#: like the held-out gusts (so no training draw meets them), none of the held-out ones.
VALIDATION_GUSTS: tuple[Gust, ...] = (
    Gust(1.5, 2.5, 0.4),
    Gust(2.5, 1.5, 0.6),
    Gust(3.0, 2.0, 0.5),
)


def gust(rng: np.random.Generator, settle_time: float, low: float, high: float) -> Gust:
    """A training start drawn from ``rng``: two heights and a switch within the settle.

    Heights lie on the half-step grid ``low + GUST_STEP * (k + 0.5)``, which never meets
    the whole-step heights of :data:`EVAL_GUSTS`; the switch is a whole action in
    ``[ACTION_TIME, settle_time - ACTION_TIME]``.
    """
    slots = max(1, round((high - low) / GUST_STEP))
    heights = low + GUST_STEP * (rng.integers(0, slots, size=2) + 0.5)
    actions = max(1, round(settle_time / ACTION_TIME))
    switch = ACTION_TIME * int(rng.integers(1, max(2, actions)))
    return Gust(heights[0], heights[1], switch)


class PerpendicularFlapFastEnv(PerpendicularFlapEnv):
    """Damp the flap's swing after a gust, on the flap's training case (module docstring).

    * **Action** ``(1,)``: the jet centre, as :class:`PerpendicularFlapEnv`.
    * **Observation** ``(6,)``: the tip's displacement ``(dx, dy)``, its velocity
      ``(vx, vy)`` and the force on the tip ``(fx, fy)``. ``observe="watchpoint"``
      (default): from the solid's watch point, the velocity over the last window.
      ``observe="precice"``: read through preCICE (module docstring), the velocity over
      the last action, the force the fluid's at its face nearest the tip.
    * **Reward**: ``-mean |d|`` over the step's windows (metres), as the parent.
    * **Episode**: ``episode_time`` seconds (default 3: 30 actions) after a
      ``settle_time`` gust (default 1 s); truncated at the end, no terminal state.
    * ``uncontrolled=True``: after the gust the inlet carries the reference inflow (the
      parabola across the whole inlet, as the packaged case's uncontrolled flap) whatever
      the action: the flap that a controller is judged against (``gymprecice baseline``).
    * ``double=True``: the same controller against gymprecice's preCICE test double and a
      scripted flap (:mod:`gymprecice_tutorials.perpendicular_flap.double`), no solvers
      needed: what ``gymprecice train perpendicular-flap-fast --double`` runs. The
      scripted flap stands in for fluid and solid together, so it is the same whichever
      ``solid`` is named.
    """

    def __init__(
        self,
        options: Mapping[str, Any] | str | Path | None = None,
        idx: int = 0,
        *,
        solid: str = "dealii",
        episode_time: float = 3.0,
        settle_time: float = 1.0,
        uncontrolled: bool = False,
        double: bool = False,
        observe: str = "watchpoint",
        run_root: str | Path | None = None,
        **kwargs: Any,
    ) -> None:
        check_solid(solid)
        if observe not in ("watchpoint", "precice"):
            raise ValueError(f"observe must be 'watchpoint' or 'precice', got {observe!r}")
        if observe == "precice" and (double or options is not None):
            raise ValueError(
                "observe='precice' edits the packaged training case (a tip mesh, two more "
                "coupling schemes); it runs on the real solvers, without options or double"
            )
        if observe == "precice" and kwargs.get("observation") == "history":
            raise ValueError(
                "observation='history' keeps the watch point's past; with observe='precice' "
                "leave it out"
            )
        self.observe = observe
        self.episode_time, self.settle_time = episode_timing(ACTION_TIME, episode_time, settle_time)
        end_time = self.settle_time + self.episode_time
        if options is None and double:
            options = write_case_files(
                "perpendicular-flap-fast-double", flap_double.double_case_files(end_time), run_root
            )
        elif options is None:
            name = "perpendicular-flap-fast" + ("" if solid == "dealii" else f"-{solid}")
            options = write_case_files(
                name + ("-precice" if observe == "precice" else ""),
                fast_case_files(end_time, observe, solid),
                run_root,
            )
        elif double:
            raise ValueError(
                "double=True runs the packaged training case on the test double; with a case "
                "of your own (options) leave double out"
            )
        super().__init__(options, idx, solid=solid, run_root=run_root, **kwargs)
        if not any(solver.kind == "openfoam" for solver in self.config.solvers.values()):
            # No fluid mesh a plugin could read (the test double's scripted flap): give the
            # controller the training case's inlet faces.
            self.set_interface_vertices(self.INLET, flap_double.training_inlet().coordinates)
        if observe == "precice":
            self.set_interface_vertices("tip", [TIP])
            self.set_interface_vertices("force", [TIP])
        self._last_tip: np.ndarray | None = None  # the previous action's tip (precice route)
        size = 6 + (2 * TIP_HISTORY if self.observation == "history" else 0)
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, shape=(size,), dtype=np.float32)
        self.uncontrolled = bool(uncontrolled)
        self.start: Gust | None = None
        self._split, self._split_seed = "train", None

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start the coupled run, drive it through this episode's gust, return the state.

        ``options={"split": "eval"}`` takes :data:`EVAL_GUSTS` ``[seed % 3]`` (``seed``
        0 when none is given), or ``[k]`` with ``"start": k``; ``"validation"`` likewise
        :data:`VALIDATION_GUSTS`; ``"train"`` draws a training gust from the seed.
        """
        self._split, self._split_seed = read_split(
            options, seed, len(EVAL_GUSTS), "gusts", len(VALIDATION_GUSTS)
        )
        obs, info = super().reset(seed=seed, options=options)  # draws self.start
        assert self.start is not None
        while self.time < self.settle_time - 1e-9:
            centre = self.start.centre(self.time)
            obs, _, terminated, truncated, info = super().step(np.array([centre], np.float32))
            if terminated and "diverged" in info:
                raise RuntimeError(
                    f"solver {info['diverged']['solver']!r} diverged at t = {self.time:g} s "
                    f"during the {self.settle_time} s gust, before the agent acted: "
                    f"{info['diverged']['evidence']}; the case cannot take this inflow "
                    f"(inlet_max_velocity {self.inlet_max_velocity:g} m/s)"
                )
            if terminated or truncated:
                raise RuntimeError(
                    f"the coupled run ended at t = {self.time:g} s during the {self.settle_time} s "
                    "gust; the case's max-time must exceed settle_time"
                )
        info = {**info, "start": {"gust": list(self.start), "split": self._split}}
        return obs, info

    @property
    def held_out_starts(self) -> tuple[str, ...]:
        """The held-out gusts, in the order ``reset(options={"split": "eval", "start": k})``
        takes them."""
        return tuple(f"jet {g.first:g} -> {g.second:g} m at {g.switch:g} s" for g in EVAL_GUSTS)

    @property
    def validation_starts(self) -> tuple[str, ...]:
        """The validation gusts, in the order ``reset(options={"split": "validation",
        "start": k})`` takes them."""
        return tuple(
            f"jet {g.first:g} -> {g.second:g} m at {g.switch:g} s" for g in VALIDATION_GUSTS
        )

    def _get_action(self, action: Any, write_var_list: list) -> dict:
        if not (self.uncontrolled and self.time >= self.settle_time - 1e-9):
            return super()._get_action(action, write_var_list)
        geometry = self.interface_geometry[self.INLET]
        velocity_x = jet_profile(
            geometry.coordinates[:, 1],
            INLET_HEIGHT / 2.0,
            INLET_HEIGHT,
            mean_velocity=2.0 / 3.0 * self.inlet_max_velocity,
            areas=geometry.areas,
        )
        velocity = np.column_stack([velocity_x, np.zeros_like(velocity_x)])
        return {ref: velocity for ref in write_var_list}

    def _get_observation(self, read_data: Any, read_var_list: list) -> np.ndarray:
        state = super()._get_observation(read_data, read_var_list)  # the reward's rows too
        if self.observe == "precice":
            return self._precice_observation(read_data)
        rows = self._tip.data
        displacement = self._tip.field("Displacement", rows[-2:])
        if len(displacement) == 2:
            velocity = (displacement[1] - displacement[0]) / WINDOW
        else:
            velocity = np.zeros(2)
        return np.concatenate([state[:2], velocity, state[2:]]).astype(np.float32)

    def _precice_observation(self, read_data: Any) -> np.ndarray:
        """The tip's state as preCICE mapped it onto the controller's tip vertex."""
        displacement = np.asarray(read_data["Displacement-tip"], dtype=float).reshape(-1)[:2]
        force = np.asarray(read_data["Force-force"], dtype=float).reshape(-1)[:2]
        previous = self._last_tip
        velocity = np.zeros(2) if previous is None else (displacement - previous) / ACTION_TIME
        self._last_tip = displacement
        return np.concatenate([displacement, velocity, force]).astype(np.float32)

    def _close_external_resources(self) -> None:
        super()._close_external_resources()
        self._last_tip = None

    def _initial_action(self) -> np.ndarray:
        """Choose this episode's start; the run's first window is the gust's first height.

        Core calls it during ``reset()`` once the seed is applied and the solvers run.
        """
        low, high = float(self.action_space.low[0]), float(self.action_space.high[0])
        fixed = fixed_start(self._split, self._split_seed, EVAL_GUSTS, VALIDATION_GUSTS)
        self.start = fixed or gust(self.np_random, self.settle_time, low, high)
        return np.array([self.start.first], dtype=np.float32)


def main(argv: Sequence[str] | None = None) -> int:  # pragma: no cover - a manual probe
    """Run one uncontrolled episode (jet in the middle) from each held-out start."""
    env = PerpendicularFlapFastEnv()
    try:
        for k in range(len(EVAL_GUSTS)):
            env.reset(seed=k, options={"split": "eval"})
            total, steps = 0.0, 0
            while True:
                _, reward, terminated, truncated, _ = env.step(np.array([2.0], np.float32))
                total, steps = total + reward, steps + 1
                if terminated or truncated:
                    break
            print(f"start {k}: mean |d| {-total / steps:.4f} m over {steps} actions")
    finally:
        env.close()
    return 0
