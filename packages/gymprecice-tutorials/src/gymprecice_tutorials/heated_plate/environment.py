"""HeatedPlate-v0: hold the plate's interface temperature at a setpoint with a heater.

Task
----
A plate (1 x 0.25, conductivity 100 W/(m K), diffusivity 1 m²/s) lies under a channel
flow entering at 300 K. A heater holds the plate's bottom at a temperature the agent
chooses; the agent must keep the mean temperature of the plate's top (the fluid-solid
interface) at a setpoint while the flow carries heat away. Two things make feedback
matter: the fluid above the plate warms up over the episode (so the heater temperature
that holds the setpoint drifts down), and the inflow velocity steps to another value at
an instant the agent does not know (a faster flow cools the plate).

* **Action** ``(1,)``: the heater temperature in K, within ``[300, 340]`` (clipped). The
  case ramps it linearly across the step's 10 time windows.
* **Observation** ``(5,)``: the mean interface temperature minus the setpoint (K), its
  change over the last step (K), the heater temperature minus 310 K (the tutorial's fixed
  bottom temperature), the inflow velocity (m/s), and the error integrated over the
  episode so far (K s), what a PID's integral term sums. Without the last the controller
  cannot tell a lasting offset from a passing one, and holds the interface below the
  setpoint after a faster inflow; five SAC seeds track the setpoint better with it, from
  every held-out start (docs/benchmark.md).
  ``observation="state"`` gives the first four only, ``(4,)``, the observation before it.
* **Reward**: ``-(|T - T_set| + actuation_cost * |T_heater - 310 K|)`` with ``T`` the mean
  interface temperature at the step's end: the tracking error in K plus the heater's
  departure from the tutorial's 310 K, weighted by ``actuation_cost`` (default 0.02).
* **Episode**: each ``reset()`` first drives the coupled case for ``settle_time``
  (default 0.3 s, not part of the episode) at the tutorial's conditions (heater 310 K,
  inflow 0.1 m/s); the episode then lasts ``episode_time`` (default 2 s, 20 actions of
  0.1 s) and is truncated at its end. There is no terminal state.

What a start is
---------------
A start is a setpoint and an inflow step ``(setpoint, step_time, velocity)``: the inflow
changes from 0.1 m/s to ``velocity`` at ``step_time`` (seconds into the episode). Training
draws starts from the episode seed on a grid; ``reset(options={"split": "eval"})`` takes
:data:`EVAL_STARTS` ``[seed % 3]``, which lie between training's grid points.

The solid
---------
``solid="openfoam"`` (laplacianFoam, 32 x 16 cells) or ``solid="fenics"`` (the FEniCS
script, 100 x 25 linear elements, run by the gymprecice-fenics plugin in its solver
environment). Both are the same plate: measured over one uncontrolled episode, their mean
interface temperatures agree to within :data:`SOLID_AGREEMENT_K` (see docs/training.md).
``double=True`` runs the env on gymprecice's test double, a lumped plate
(:mod:`.double`), for tests without solvers.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, NamedTuple

import gymnasium as gym
import numpy as np

from gymprecice.env.core import Adapter
from gymprecice.plugin.fields import Overlay
from gymprecice_tutorials.case_files import write_case_files
from gymprecice_tutorials.episodes import fixed_start, read_split
from gymprecice_tutorials.heated_plate.packaged_case import SOLIDS, case_files

__all__ = [
    "ACTION_TIME",
    "OBSERVATIONS",
    "EVAL_STARTS",
    "HEATER_RANGE",
    "SOLIDS",
    "HeatedPlateEnv",
    "Start",
    "case_files",
    "draw_start",
]

#: the time one action spans (10 preCICE windows of ``WINDOW``)
ACTION_TIME = 0.1
#: the heater temperature range (K) and the tutorial's fixed bottom temperature
HEATER_RANGE = (300.0, 340.0)
REFERENCE_HEATER = 310.0
#: what the controller may see (``observation=``): the first four numbers of the module
#: docstring, or those and the episode's integrated error (the default)
OBSERVATIONS = ("state", "integral")
#: the tutorial's inflow velocity (m/s), before an episode's step
REFERENCE_INFLOW = 0.1
INFLOW_RANGE = (0.03, 0.3)
SETPOINT_RANGE = (304.0, 308.0)
#: the largest difference (K) between the two plates' mean interface temperature over one
#: uncontrolled episode that the real-stack test accepts
SOLID_AGREEMENT_K = 0.05


class Start(NamedTuple):
    """An episode's setpoint (K) and its inflow step: to ``velocity`` at ``step_time``."""

    setpoint: float
    step_time: float
    velocity: float


#: held-out starts (``reset(options={"split": "eval"})``, ``seed % 3``): setpoints, step
#: times and velocities half a grid step away from every training draw (a step time is
#: when, after settling, the inflow changes; it lies on the 0.1 s action grid)
EVAL_STARTS = (
    Start(305.25, 0.5, 0.045),
    Start(306.75, 1.1, 0.255),
    Start(307.25, 0.7, 0.165),
)

#: validation starts (``reset(options={"split": "validation"})``), which choose the model
#: a training run keeps: between the training grid's points like the held-out starts,
#: none of them
VALIDATION_STARTS = (
    Start(305.75, 0.9, 0.135),
    Start(306.25, 0.3, 0.225),
    Start(307.75, 0.5, 0.075),
)


def draw_start(rng: np.random.Generator, episode_time: float) -> Start:
    """A training start: setpoint on a 0.5 K grid, step time on even tenths of a second
    (the action grid's every other instant), velocity on a 0.03 m/s grid; the held-out
    starts lie between grid points (quarter kelvins, odd tenths, 0.015 m/s off)."""
    setpoints = np.arange(SETPOINT_RANGE[0], SETPOINT_RANGE[1] + 1e-9, 0.5)
    last = max(0.2, min(1.4, episode_time - 0.1))
    times = np.arange(0.2, last + 1e-9, 0.2)
    velocities = np.arange(INFLOW_RANGE[0], INFLOW_RANGE[1] + 1e-9, 0.03)
    return Start(
        float(rng.choice(setpoints)), float(rng.choice(times)), float(rng.choice(velocities))
    )


class HeatedPlateEnv(Adapter):
    """Drive the heater to hold the plate's interface temperature (see the module docstring)."""

    PLATE = "plate"
    HEATER = "heater"
    INLET = "inlet"

    def __init__(
        self,
        options: Mapping[str, Any] | str | Path | None = None,
        idx: int = 0,
        *,
        solid: str = "openfoam",
        episode_time: float = 2.0,
        settle_time: float = 0.3,
        actuation_cost: float = 0.02,
        observation: str = "integral",
        uncontrolled: bool = False,
        double: bool = False,
        run_root: str | Path | None = None,
        **kwargs: Any,
    ) -> None:
        for name, value in (("episode_time", episode_time), ("settle_time", settle_time)):
            steps = value / ACTION_TIME
            if not math.isfinite(value) or value < 0 or abs(steps - round(steps)) > 1e-9:
                raise ValueError(
                    f"{name} must be a multiple of {ACTION_TIME} s (one action), got {value}"
                )
        if episode_time <= 0 or settle_time <= 0:
            # The interface temperature reaches the controller at the end of a window: the
            # first observation of an episode needs at least one settling step before it.
            raise ValueError(
                f"episode_time and settle_time must be positive, got {episode_time} and "
                f"{settle_time}"
            )
        if observation not in OBSERVATIONS:
            raise ValueError(
                f"observation must be one of {', '.join(OBSERVATIONS)}, got {observation!r}"
            )
        self.solid = solid
        self.observation = observation
        self.episode_time = float(episode_time)
        self.settle_time = float(settle_time)
        end_time = self.settle_time + self.episode_time
        if options is None and double:
            from gymprecice_tutorials.heated_plate.double import double_case_files

            options = write_case_files("heated-plate-double", double_case_files(end_time), run_root)
        elif options is None:
            options = write_case_files(*self.packaged_case(end_time), run_root)
        elif double:
            raise ValueError(
                "double=True runs the packaged case on the test double; with a case of your "
                "own (options) leave double out"
            )
        super().__init__(options, idx, run_root=run_root, **kwargs)
        if not any(s.kind == "openfoam" for s in self.config.solvers.values()):
            # No fluid mesh a plugin could read (the test double's lumped plate): any
            # vertices do, the controller writes uniform values and reads a mean.
            for name, n in ((self.INLET, 41), (self.HEATER, 32), (self.PLATE, 161)):
                x = np.linspace(0.0, 1.0, n)
                self.set_interface_vertices(name, np.column_stack([x, np.zeros(n)]))
        self.actuation_cost = float(actuation_cost)
        self.uncontrolled = bool(uncontrolled)
        self.action_space = gym.spaces.Box(
            low=np.float32(HEATER_RANGE[0]), high=np.float32(HEATER_RANGE[1]), shape=(1,)
        )
        size = 5 if observation == "integral" else 4
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, shape=(size,), dtype=np.float32)
        self.start = EVAL_STARTS[0]
        self._split, self._split_seed = "train", None
        self._heater = REFERENCE_HEATER
        self._temperature = math.nan
        self._previous = math.nan
        self._integral = 0.0

    def packaged_case(self, end_time: float) -> tuple[str, dict[str, str]]:
        """The packaged case's name and files for a run ending at ``end_time`` (a training
        variant overrides this)."""
        return f"heated-plate-{self.solid}", case_files(self.solid, end_time)

    @property
    def held_out_starts(self) -> tuple[str, ...]:
        """The held-out starts, in the order ``reset(options={"split": "eval", "start": k})``
        takes them."""
        return tuple(
            f"setpoint {s.setpoint:g} K, inflow -> {s.velocity:g} m/s at {s.step_time:g} s"
            for s in EVAL_STARTS
        )

    @property
    def validation_starts(self) -> tuple[str, ...]:
        """The validation starts, in the order ``reset(options={"split": "validation",
        "start": k})`` takes them."""
        return tuple(
            f"setpoint {s.setpoint:g} K, inflow -> {s.velocity:g} m/s at {s.step_time:g} s"
            for s in VALIDATION_STARTS
        )

    # -- the controller's physics ------------------------------------------------------------
    def inflow_velocity(self, time: float) -> float:
        """The inflow velocity (m/s) at simulated ``time``: the episode's step after settling."""
        if time < self.settle_time + self.start.step_time - 1e-9:
            return REFERENCE_INFLOW
        return self.start.velocity

    # -- rendering -------------------------------------------------------------------------
    #: ``render_mode="rgb_array"``: fluid and plate temperature, one frame per action
    metadata: dict[str, Any] = {"render_modes": ["rgb_array"], "render_fps": 10}

    @property
    def render_fields(self) -> dict[str, tuple[str, ...]]:  # type: ignore[override]
        """The fluid's and the plate's temperature (one lumped solver on the test double).

        The plate's ``T`` comes from laplacianFoam's time directories or from the FEniCS
        script's field file, whichever plate the env runs.
        """
        if "fluid" in self.config.solvers:
            if "solid" in self.config.solvers:
                return {"fluid": ("T",), "solid": ("T",)}
            return {"fluid": ("T",)}
        return {solver: ("T-fluid", "T") for solver in self.config.solvers}

    def _render_overlay(self) -> Overlay:
        """The heater's temperature under the plate."""
        heater = self.heater_temperature(self.last_action)
        return Overlay(
            text=[f"heater T = {heater:.2f} K (reference {REFERENCE_HEATER:g} K)"],
            arrows=[(x, -0.3, 0.0, 0.08) for x in (0.25, 0.5, 0.75)],
        )

    def heater_temperature(self, action: Any) -> float:
        """The heater temperature an action asks for, clipped to the action space."""
        if self.uncontrolled or self.time < self.settle_time - 1e-9:
            return REFERENCE_HEATER
        value = float(np.asarray(action, dtype=float).reshape(-1)[0])
        return float(np.clip(value, *HEATER_RANGE))

    def plate_temperature(self, values: np.ndarray) -> float:
        """The mean interface temperature, weighted by face area where the fluid gives it."""
        areas = self.interface_geometry[self.PLATE].areas
        values = np.asarray(values, dtype=float).reshape(-1)
        if areas is None or len(areas) != len(values):
            return float(np.mean(values))
        return float(np.average(values, weights=np.asarray(areas, dtype=float)))

    # -- the four user methods -------------------------------------------------------------
    def _get_action(self, action: Any, write_var_list: list) -> dict:
        self._heater = self.heater_temperature(action)
        # The velocity written now holds over the step: the one at the step's start.
        velocity = self.inflow_velocity(self.time)
        out: dict[Any, np.ndarray] = {}
        for ref in write_var_list:
            n = len(self.interface_geometry[ref.interface].coordinates)
            if ref.interface == self.INLET:
                out[ref] = np.column_stack([np.full(n, velocity), np.zeros(n)])
            else:
                out[ref] = np.full(n, self._heater)
        return out

    def _get_observation(self, read_data: Any, read_var_list: list) -> np.ndarray:
        (ref,) = [r for r in read_var_list if r.interface == self.PLATE]
        self._previous = self._temperature
        self._temperature = self.plate_temperature(read_data[ref])
        change = 0.0 if math.isnan(self._previous) else self._temperature - self._previous
        error = self._temperature - self.start.setpoint
        if self.time > self.settle_time + 1e-9:  # the episode's steps, not the settling
            self._integral += error * ACTION_TIME
        values = [error, change, self._heater - REFERENCE_HEATER, self.inflow_velocity(self.time)]
        if self.observation == "integral":
            values.append(self._integral)
        return np.array(values, dtype=np.float32)

    def _get_reward(self) -> float:
        error = abs(self._temperature - self.start.setpoint)
        return -float(error + self.actuation_cost * abs(self._heater - REFERENCE_HEATER))

    def _close_external_resources(self) -> None:
        self._temperature = math.nan
        self._previous = math.nan
        self._integral = 0.0

    def _initial_action(self) -> np.ndarray:
        """Choose this episode's start; every run begins at the tutorial's 310 K heater."""
        fixed = fixed_start(self._split, self._split_seed, EVAL_STARTS, VALIDATION_STARTS)
        self.start = fixed or draw_start(self.np_random, self.episode_time)
        self._heater = REFERENCE_HEATER
        self._integral = 0.0
        return np.array([REFERENCE_HEATER], dtype=np.float32)

    # -- Gymnasium API -----------------------------------------------------------------------
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start the coupled run, drive it through ``settle_time``, return the state.

        ``options={"split": "eval"}`` takes :data:`EVAL_STARTS` ``[seed % 3]`` (``seed`` 0
        when none is given), or ``[k]`` with ``"start": k``; ``"validation"`` likewise
        :data:`VALIDATION_STARTS`; ``"train"`` draws a training start from the seed.
        """
        self._split, self._split_seed = read_split(
            options, seed, len(EVAL_STARTS), "starts", len(VALIDATION_STARTS)
        )
        obs, info = super().reset(seed=seed, options=options)  # draws self.start
        while self.time < self.settle_time - 1e-9:
            obs, _, terminated, truncated, info = super().step(
                np.array([REFERENCE_HEATER], np.float32)
            )
            if terminated or truncated:
                raise RuntimeError(
                    f"the coupled run ended at t = {self.time:g} s while settling; the case's "
                    "max-time must exceed settle_time"
                )
        info = {**info, "start": {**self.start._asdict(), "split": self._split}}
        return obs, info

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Core's step, plus the applied heater temperature and the metrics in ``info``."""
        obs, reward, terminated, truncated, info = super().step(action)
        info["action"] = [self._heater]
        info["metrics"] = {
            "interface_temperature": self._temperature,
            "tracking_error": abs(self._temperature - self.start.setpoint),
            "heater_temperature": self._heater,
            "inflow_velocity": float(obs[3]),
        }
        return obs, reward, terminated, truncated, info


def run_constant(
    env: HeatedPlateEnv, heater: float = REFERENCE_HEATER, *, seed: int = 0, split: str = "eval"
) -> dict[str, np.ndarray]:
    """One episode at a constant heater temperature; returns the time series."""
    obs, _ = env.reset(seed=seed, options={"split": split})
    times, temperatures, rewards = [env.time], [obs[0] + env.start.setpoint], []
    while True:
        obs, reward, terminated, truncated, info = env.step(np.array([heater], np.float32))
        times.append(env.time)
        temperatures.append(info["metrics"]["interface_temperature"])
        rewards.append(reward)
        if terminated or truncated:
            break
    return {
        "time": np.asarray(times),
        "temperature": np.asarray(temperatures),
        "reward": np.asarray(rewards),
    }


def main(argv: Sequence[str] | None = None) -> int:  # pragma: no cover - a manual probe
    """``python -m gymprecice_tutorials.heated_plate.environment``: one constant-heater episode."""
    import argparse
    import time

    parser = argparse.ArgumentParser(description=main.__doc__)
    parser.add_argument("--solid", choices=sorted(SOLIDS), default="openfoam")
    parser.add_argument("--heater", type=float, default=REFERENCE_HEATER)
    parser.add_argument("--episode-time", type=float, default=2.0)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--run-root", default=None)
    args = parser.parse_args(argv)
    env = HeatedPlateEnv(solid=args.solid, episode_time=args.episode_time, run_root=args.run_root)
    started = time.perf_counter()
    try:
        result = run_constant(env, args.heater, seed=args.seed)
    finally:
        env.close()
    for t, temperature in zip(result["time"], result["temperature"]):
        print(f"t = {t:.2f} s  T = {temperature:.4f} K")
    print(
        f"{len(result['reward'])} steps, return {result['reward'].sum():.4f}, "
        f"{time.perf_counter() - started:.1f} s wall-clock ({args.solid} plate)"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
