"""HeatedRod-v0: hold a rod's temperature at a setpoint with three heaters, under a heat load.

Task
----
A rod of unit length (diffusivity 1 m²/s) has both ends held at 0 K. The agent sets the
heat of three heaters (at x = 0.25, 0.5, 0.75) and must keep the mean of four sensed
temperatures (x = 0.1, 0.4, 0.6, 0.9) at a setpoint. The rod starts cold, and at an
instant the agent is not told a heat load (a sink at x = 0.6) switches on.

* **Action** ``(3,)``: each heater's heat in K/s, within ``[0, 50]`` (clipped).
* **Observation** ``(4,)``: the four sensed temperatures minus the setpoint (K).
* **Reward**: ``-(|mean T - T_set| + ACTUATION_COST * mean heat)``: the tracking error in
  K plus a small price on heating.
* **Episode**: 1 s of simulated time, 20 actions of 0.05 s (two preCICE windows each),
  truncated at its end; no terminal state.
* ``info["metrics"]``: ``tracking_error`` (K), ``error`` (mean T - T_set, signed),
  ``mean_temperature`` (K) and ``heat`` (the mean heater, K/s).

Starts
------
A start is ``(setpoint, load_time, load)``: training draws it from the episode's seed on
a grid; ``reset(options={"split": "eval", "start": k})`` takes :data:`EVAL_STARTS` ``[k]``
(``seed % 3`` without ``"start"``), which lie between the grid's points, so no training
episode ever sees them.

The case
--------
The packaged case (``case/``) couples the controller to one solver of kind ``command``
(core's own plugin): ``case/rod/solver.py``, a finite-difference heat equation written
against the pyprecice v3 API. ``double=True`` couples it through gymprecice's preCICE
test double instead of real preCICE: the same physics, with no preCICE installed.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any, NamedTuple

import gymnasium as gym
import numpy as np

from gymprecice.core import Adapter

__all__ = [
    "CASE_DIR",
    "EVAL_STARTS",
    "HeatedRodEnv",
    "Start",
    "draw_start",
    "packaged_config",
]

CASE_DIR = Path(__file__).resolve().parent / "case"
#: the module gymprecice couples through on the test double (``double=True``)
DOUBLE_LIBRARY = "gymprecice.testing.fake_precice"
HEAT_RANGE = (0.0, 50.0)
#: the heat (K/s) of every heater in the uncontrolled rod: it holds 0.15 K without load
REFERENCE_HEAT = 24.0
ACTUATION_COST = 1e-4
#: the controller's vertices: the same points as the rod's own (case/rod/solver.py)
HEATERS = [[0.25, 0.0], [0.5, 0.0], [0.75, 0.0]]
LOAD = [[0.6, 0.0]]
SENSORS = [[0.1, 0.0], [0.4, 0.0], [0.6, 0.0], [0.9, 0.0]]


class Start(NamedTuple):
    """An episode's setpoint (K) and its load: ``load`` K/s from ``load_time`` s on."""

    setpoint: float
    load_time: float
    load: float


#: held-out starts: setpoints, load times and loads half a grid step from every training draw
EVAL_STARTS = (
    Start(0.13, 0.45, -9.0),
    Start(0.17, 0.35, -27.0),
    Start(0.11, 0.65, -15.0),
)


def draw_start(rng: np.random.Generator) -> Start:
    """A training start: setpoint on a 0.02 K grid, load time on a 0.1 s grid, load on a
    6 K/s grid (the held-out starts lie between their points)."""
    return Start(
        float(rng.choice(np.round(np.arange(0.10, 0.201, 0.02), 2))),
        float(rng.choice(np.round(np.arange(0.2, 0.71, 0.1), 1))),
        float(rng.choice(np.arange(0.0, -30.1, -6.0))),
    )


def packaged_config(double: bool = False) -> dict[str, Any]:
    """The packaged case's configuration; ``double``: coupled through the test double."""
    config = json.loads((CASE_DIR / "gymprecice-config.json").read_text())
    if double:
        config["environment"]["name"] = "heated-rod-double"
        config["precice"]["library"] = DOUBLE_LIBRARY
    return config


class HeatedRodEnv(Adapter):
    """Heat a rod to a setpoint under an unknown load (see the module docstring)."""

    def __init__(
        self,
        options: Mapping[str, Any] | str | Path | None = None,
        idx: int | None = None,
        *,
        double: bool = False,
        uncontrolled: bool = False,
        run_root: str | Path | None = None,
    ) -> None:
        if options is not None and double:
            raise ValueError(
                "double=True runs the packaged case on the test double; with a case of your "
                "own (options) set its precice.library instead"
            )
        case_dir = CASE_DIR if options is None else None
        if options is None:
            options = packaged_config(double)
        super().__init__(options, idx, run_root=run_root, case_dir=case_dir)
        # A "command" solver has no geometry plugin: the controller's vertices, by hand.
        self.set_interface_vertices("heater", HEATERS)
        self.set_interface_vertices("load", LOAD)
        self.set_interface_vertices("sensor", SENSORS)
        self.uncontrolled = bool(uncontrolled)
        self.action_space = gym.spaces.Box(
            *HEAT_RANGE, shape=(3,), dtype=np.float32
        )
        self.observation_space = gym.spaces.Box(
            -np.inf, np.inf, shape=(4,), dtype=np.float32
        )
        self.start = EVAL_STARTS[0]
        self._split, self._split_start = "train", 0
        self._heat = np.full(3, REFERENCE_HEAT)
        self._temperature = np.zeros(4)

    @property
    def held_out_starts(self) -> tuple[str, ...]:
        """The held-out starts' labels, in the order ``reset(options={"split": "eval",
        "start": k})`` takes them."""
        return tuple(
            f"setpoint {s.setpoint:g} K, load {s.load:g} K/s at {s.load_time:g} s"
            for s in EVAL_STARTS
        )

    # -- the four user methods -------------------------------------------------------------
    def _get_action(
        self, action: Any, write_var_list: list
    ) -> dict[str, np.ndarray]:
        heat = np.clip(np.asarray(action, dtype=float).reshape(3), *HEAT_RANGE)
        self._heat = np.full(3, REFERENCE_HEAT) if self.uncontrolled else heat
        # self.time is the step's start: the load holds over the whole step
        load = (
            self.start.load if self.time >= self.start.load_time - 1e-9 else 0.0
        )
        return {"heater": self._heat, "load": np.array([load])}

    def _get_observation(
        self, read_data: Any, read_var_list: list
    ) -> np.ndarray:
        # zeros at reset(): the rod starts at 0 K (its exchange has no initialize="true")
        self._temperature = np.asarray(read_data["sensor"], dtype=float)
        return (self._temperature - self.start.setpoint).astype(np.float32)

    def _get_reward(self) -> float:
        return -(self._error() + ACTUATION_COST * float(self._heat.mean()))

    def _close_external_resources(self) -> None:
        pass  # the env opens no file of its own

    def _initial_action(self) -> np.ndarray:
        """Choose the episode's start (after reset seeded ``np_random``); heaters start at
        the reference heat."""
        if self._split == "eval":
            self.start = EVAL_STARTS[self._split_start % len(EVAL_STARTS)]
        else:
            self.start = draw_start(self.np_random)
        return np.full(3, REFERENCE_HEAT, dtype=np.float32)

    def _error(self) -> float:
        return abs(float(self._temperature.mean()) - self.start.setpoint)

    # -- Gymnasium API ---------------------------------------------------------------------
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start an episode. ``options={"split": "eval", "start": k}`` starts from held-out
        start ``k`` (``seed % 3`` without ``"start"``); otherwise a training start is drawn
        from the seed."""
        options = options or {}
        split, start = options.get("split", "train"), options.get("start")
        if split not in ("train", "eval"):
            raise ValueError(
                f"reset option split must be 'train' or 'eval', got {split!r}"
            )
        if start is not None and not (
            isinstance(start, int)
            and not isinstance(start, bool)
            and 0 <= start < 3
        ):
            raise ValueError(
                f"reset option start={start!r}: the held-out starts are 0, 1, 2"
            )
        self._split = split
        self._split_start = start if start is not None else (seed or 0)
        self._heat = np.full(3, REFERENCE_HEAT)
        obs, info = super().reset(seed=seed, options=options)
        return obs, {**info, "start": {**self.start._asdict(), "split": split}}

    def step(
        self, action: Any
    ) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Core's step, with the heat applied and the metrics in ``info``."""
        obs, reward, terminated, truncated, info = super().step(action)
        mean = float(self._temperature.mean())
        info["action"] = self._heat.tolist()
        info["metrics"] = {
            "tracking_error": self._error(),
            "error": mean - self.start.setpoint,
            "mean_temperature": mean,
            "heat": float(self._heat.mean()),
        }
        return obs, reward, terminated, truncated, info
