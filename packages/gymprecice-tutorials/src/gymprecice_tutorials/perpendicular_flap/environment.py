"""Gymnasium environment of the perpendicular flap, and an open-loop sinusoidal controller.

Task: an elastic flap stands in a channel; a parabolic jet enters through the inlet and the
agent chooses where along the inlet the jet is centred. The fluid pushes the flap, the
flap bends and springs back; the agent should keep the flap upright.

* **Action** ``(1,)``: the jet centre's height ``y_c`` on the inlet, within
  ``[h/2, H - h/2]`` (``H = 4`` the inlet height, ``h`` the jet height, default 2), so the
  whole jet stays on the inlet. Out-of-range actions are clipped. Whatever the position,
  the jet carries the flow rate of the reference inflow (a parabola of peak
  ``inlet_max_velocity`` across the full inlet), so the agent steers the flow but cannot
  change how much of it there is.
* **Observation** ``(4,)``: the flap tip's displacement ``(dx, dy)`` and the force on the
  tip ``(fx, fy)`` at the end of the step, from the solid's preCICE watch point
  ``Flap-Tip`` (``precice-Solid-watchpoint-Flap-Tip.log`` in the solid's directory).
  ``observation="history"`` appends the tip's displacement at the ends of the
  :data:`TIP_HISTORY` steps before, ``(10,)`` (zeros before the run's first steps):
  one sample of the tip says where it is, not where it swings; a short history gives the
  phase and the speed of the swing.
* **Reward**: ``-mean |d|`` over the time windows of the step, the mean magnitude of the
  tip displacement (metres, so a reward of -0.1 means the tip was 10 cm off its rest
  position on average). Averaging over every window of the step, rather than taking the
  last one, stops the agent from timing a swing through zero at the step's end.
* **Episode end**: truncated at the coupling's ``max-time`` (5 s, 50 steps of 0.1 s with
  the case's ``actions.windows = 10``). There is no terminal state.

``setup="precice"`` runs preCICE's own perpendicular-flap tutorial instead
(:mod:`.precice_setup`): its fluid mesh and its fluid starting at 10 m/s, with a uniform
inflow whose speed (m/s, in ``[0, 2 * inlet_max_velocity]``) is the action, 10 m/s to
begin with. Held at 10 m/s it is the setup whose published tip series
``python -m gymprecice_tutorials.perpendicular_flap.validate`` compares with.

The env reads the watch point rather than asking preCICE for data: the flap's tip is one
point of the solid, and preCICE's watch point already interpolates displacement and force
there. Each observation waits (``watch_timeout`` seconds at most) for the solid's row of
the current time. That wait is also what keeps the env in step with the physics: the
controller only writes (explicit coupling, nothing to receive), so preCICE's ``advance``
does not hold it back while fluid and solid iterate a window.

The solid
---------
``solid="dealii"`` (default: the deal.II-preCICE adapter's ``elasticity``, 3 x 18 cells
of degree 4) or ``solid="fenics"`` (preCICE's FEniCS flap, ``case/solid-fenics/solid.py``,
quadratic triangles with the deal.II solid's coupling vertices, run by the
gymprecice-fenics plugin in the FEniCS solver environment). Both are the same flap
(0.1 x 1, E = 4 MPa, nu = 0.3, 3000 kg/m³), the same preCICE participant ``Solid`` with
the same watch point, so the env's code does not change. Uncontrolled, their swings
agree within
:data:`~gymprecice_tutorials.perpendicular_flap.swing.SOLID_AGREEMENT` (measured in
docs/tutorials/perpendicular-flap.md, "Two solids"). The tip force of the observation is
the solid's nodal force at the watch point: it depends on where the coupling vertices
are, which is why the FEniCS solid copies the deal.II solid's.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from gymprecice.env.core import Adapter
from gymprecice.plugin.fields import Overlay
from gymprecice_tutorials.case_files import write_case_files
from gymprecice_tutorials.perpendicular_flap.packaged_case import SOLIDS, case_files, check_solid
from gymprecice_tutorials.perpendicular_flap.precice_setup import SETUPS, setup_case_files

#: what the controller may see (``observation=``): the tip now, or with its recent past
OBSERVATIONS = ("state", "history")
#: the steps of the tip's past that ``observation="history"`` shows
TIP_HISTORY = 3

__all__ = [
    "INLET_HEIGHT",
    "SOLIDS",
    "PerpendicularFlapEnv",
    "jet_profile",
    "main",
    "run_open_loop",
    "sinusoidal_jet_centre",
]

#: height of the channel inlet (x = -3, y in [0, 4])
INLET_HEIGHT = 4.0


def jet_profile(
    y: np.ndarray,
    centre: float,
    jet_height: float,
    mean_velocity: float,
    areas: np.ndarray | None = None,
) -> np.ndarray:
    """Normal velocity of a parabolic jet at inlet faces centred at heights ``y``.

    The jet is a parabola over ``[centre - h/2, centre + h/2]`` and zero elsewhere, scaled
    so the discrete flow rate ``sum(u * areas)`` equals ``mean_velocity * sum(areas)``, the
    flow rate of the reference inflow. Scaling on the actual faces (not the continuous
    parabola) keeps the flow rate exact on any mesh and at any jet position, so moving the
    jet never adds or removes fluid. ``areas`` default to equal faces.
    """
    y = np.asarray(y, dtype=float)
    weights = np.ones_like(y) if areas is None else np.asarray(areas, dtype=float)
    s = (y - (centre - jet_height / 2.0)) / jet_height  # 0 .. 1 across the jet
    shape = np.where((s > 0.0) & (s < 1.0), 4.0 * s * (1.0 - s), 0.0)
    carried = float(shape @ weights)
    if carried <= 0.0:
        raise ValueError(
            f"a jet of height {jet_height} centred at {centre} covers none of the "
            f"{len(y)} inlet faces (y from {y.min() if len(y) else 'n/a'} to "
            f"{y.max() if len(y) else 'n/a'})"
        )
    return shape * (mean_velocity * float(weights.sum()) / carried)


class PerpendicularFlapEnv(Adapter):
    """Move the inlet jet to keep the elastic flap upright (see the module docstring)."""

    #: solver name of the solid in ``gymprecice-config.json``, and its watch point
    SOLID = "solid"
    WATCH_POINT = "Flap-Tip"
    #: the controller interface the jet is written to
    INLET = "inlet"
    #: ``render_mode="rgb_array"``: fluid and bent flap, one frame per action
    metadata: dict[str, Any] = {"render_modes": ["rgb_array"], "render_fps": 10}

    def __init__(
        self,
        options: Mapping[str, Any] | str | Path | None = None,
        idx: int = 0,
        *,
        solid: str = "dealii",
        inlet_max_velocity: float = 10.0,
        jet_height: float = 2.0,
        watch_timeout: float = 120.0,
        observation: str = "state",
        setup: str = "jet",
        run_root: str | Path | None = None,
        **kwargs: Any,
    ) -> None:
        if observation not in OBSERVATIONS:
            raise ValueError(
                f"observation must be one of {', '.join(OBSERVATIONS)}, got {observation!r}"
            )
        if setup not in SETUPS:
            raise ValueError(f"setup must be one of {', '.join(SETUPS)}, got {setup!r}")
        self.observation = observation
        self.setup = setup
        self.solid = check_solid(solid)
        if options is None:
            files = (
                case_files(solid) if setup == "jet" else setup_case_files(solid, inlet_max_velocity)
            )
            options = write_case_files(f"perpendicular-flap-{setup}-{solid}", files, run_root)
        elif setup != "jet":
            raise ValueError(f"setup={setup!r} makes its own case: give no options with it")
        super().__init__(options, idx, run_root=run_root, **kwargs)
        if not 0.0 < jet_height <= INLET_HEIGHT:
            raise ValueError(f"jet_height must lie in (0, {INLET_HEIGHT}], got {jet_height}")
        self.inlet_max_velocity = float(inlet_max_velocity)
        self.jet_height = float(jet_height)
        self.watch_timeout = float(watch_timeout)
        if setup == "jet":
            low, high = jet_height / 2.0, INLET_HEIGHT - jet_height / 2.0
        else:  # the uniform inflow's speed
            low, high = 0.0, 2.0 * self.inlet_max_velocity
        self.action_space = gym.spaces.Box(
            low=np.float32(low), high=np.float32(high), shape=(1,), dtype=np.float32
        )
        size = 4 + (2 * TIP_HISTORY if observation == "history" else 0)
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, shape=(size,), dtype=np.float32)
        self._tip: Any = None  # the watch-point reader of the current episode
        self._step_rows = np.zeros((0, 0))
        self._past = np.zeros((TIP_HISTORY, 2), dtype=np.float32)  # newest first

    # -- rendering -------------------------------------------------------------------------
    @property
    def render_fields(self) -> dict[str, tuple[str, ...]]:  # type: ignore[override]
        """The fluid's speed and the flap's displacement, drawn on the bent flap.

        On the real case the fluid's ``U`` comes from OpenFOAM and the solid's
        ``displacement`` from the deal.II adapter's snapshots or the FEniCS script's field
        file; the test double's flap hands over both.
        """
        if "fluid" in self.config.solvers:
            return {"fluid": ("U",), self.SOLID: ("displacement",)}
        return {self.SOLID: ("U", "displacement")}

    def _render_overlay(self) -> Overlay:
        """The jet: where it blows in at the inlet (x = -3 m), and its centre as text."""
        if self.setup != "jet":
            speed = self.jet_centre(self.last_action)
            ys = np.linspace(0.4, INLET_HEIGHT - 0.4, 5)
            return Overlay(
                text=[f"uniform inflow {speed:.2f} m/s"],
                arrows=[(-3.0, float(y), 0.06 * speed, 0.0) for y in ys],
            )
        centre = self.jet_centre(self.last_action)
        ys = np.linspace(centre - 0.4 * self.jet_height, centre + 0.4 * self.jet_height, 5)
        return Overlay(
            text=[f"jet centre y = {centre:.2f} m (height {self.jet_height:g} m)"],
            arrows=[(-3.0, float(y), 0.6, 0.0) for y in ys],
        )

    # -- the four user methods -------------------------------------------------------------
    def _get_action(self, action: Any, write_var_list: list) -> dict:
        centre = self.jet_centre(action)
        geometry = self.interface_geometry[self.INLET]
        if self.setup == "jet":
            velocity_x = jet_profile(
                geometry.coordinates[:, 1],
                centre,
                self.jet_height,
                mean_velocity=2.0 / 3.0 * self.inlet_max_velocity,
                areas=geometry.areas,
            )
        else:  # preCICE's tutorial: the action's speed on every inlet face
            velocity_x = np.full(len(geometry.coordinates), centre)
        velocity = np.column_stack([velocity_x, np.zeros_like(velocity_x)])
        return {ref: velocity for ref in write_var_list}

    def _get_observation(self, read_data: Any, read_var_list: list) -> np.ndarray:
        if self._tip is None:  # core closes readers at every reset: open one per episode
            self._tip = self.open_output(self.SOLID, "watchpoint", point=self.WATCH_POINT)
        self._step_rows = self._tip.wait_until(self.time, self.watch_timeout)
        last = self._tip.data[-1:]
        displacement = self._tip.field("Displacement", last)[0]
        force = self._tip.field("Force", last)[0]
        obs = np.concatenate([displacement, force]).astype(np.float32)
        if self.observation == "history":
            obs = np.concatenate([obs, self._past.reshape(-1)])
            self._past = np.roll(self._past, 1, axis=0)
            self._past[0] = displacement[:2]
        return obs

    def _get_reward(self) -> float:
        rows = self._step_rows if len(self._step_rows) else self._tip.data[-1:]
        displacement = self._tip.field("Displacement", rows)
        return -float(np.mean(np.linalg.norm(displacement, axis=1)))

    def _close_external_resources(self) -> None:
        self._tip = None
        self._step_rows = np.zeros((0, 0))
        self._past = np.zeros((TIP_HISTORY, 2), dtype=np.float32)

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Core's step, plus the applied jet centre and the tip's metrics in ``info``.

        ``info["metrics"]`` holds the tip displacement at the step's end (``tip_dx``,
        ``tip_dy``) and its mean magnitude over the step (``mean_tip_displacement``, the
        negated reward): what ``gymprecice open-loop`` and ``evaluate`` record.
        """
        obs, reward, terminated, truncated, info = super().step(action)
        info["action"] = [self.jet_centre(action)]
        info["metrics"] = {
            "tip_dx": float(obs[0]),
            "tip_dy": float(obs[1]),
            "mean_tip_displacement": -float(reward),
        }
        return obs, reward, terminated, truncated, info

    # -- helpers ---------------------------------------------------------------------------
    def _initial_action(self) -> np.ndarray:
        """Start each episode with the jet in the middle of the inlet (preCICE's setup:
        its inflow of ``inlet_max_velocity``), with no past."""
        self._past = np.zeros((TIP_HISTORY, 2), dtype=np.float32)
        if self.setup != "jet":
            return np.array([self.inlet_max_velocity], dtype=np.float32)
        return np.array([INLET_HEIGHT / 2.0], dtype=np.float32)

    def jet_centre(self, action: Any) -> float:
        """The jet centre an action asks for (preCICE's setup: the inflow speed), clipped
        to the action space."""
        value = float(np.asarray(action, dtype=float).reshape(-1)[0])
        return float(np.clip(value, self.action_space.low[0], self.action_space.high[0]))


def sinusoidal_jet_centre(
    time: float, low: float, high: float, frequency: float = 0.5, phase: float = 0.0
) -> float:
    """Open-loop control: the jet centre sweeps ``[low, high]`` sinusoidally in time."""
    middle, amplitude = (low + high) / 2.0, (high - low) / 2.0
    return middle + amplitude * math.sin(2.0 * math.pi * frequency * time + phase)


def run_open_loop(
    env: PerpendicularFlapEnv, frequency: float = 0.5, max_steps: int | None = None
) -> dict[str, np.ndarray]:
    """Run one episode under :func:`sinusoidal_jet_centre`; returns the time series.

    The action of a step is the sine at the step's start time; the case's action ramp
    smooths it across the step's time windows.
    """
    low, high = float(env.action_space.low[0]), float(env.action_space.high[0])
    observation, _ = env.reset()
    times, actions, observations, rewards = [env.time], [], [observation], []
    while max_steps is None or len(actions) < max_steps:
        action = np.array([sinusoidal_jet_centre(env.time, low, high, frequency)], np.float32)
        observation, reward, terminated, truncated, _ = env.step(action)
        times.append(env.time)
        actions.append(action[0])
        observations.append(observation)
        rewards.append(reward)
        if terminated or truncated:
            break
    return {
        "time": np.asarray(times),
        "action": np.asarray(actions),
        "observation": np.asarray(observations),
        "reward": np.asarray(rewards),
    }


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m gymprecice_tutorials.perpendicular_flap.environment``: one open-loop episode."""
    parser = argparse.ArgumentParser(description=main.__doc__)
    parser.add_argument("--frequency", type=float, default=0.5, help="sweeps per second")
    parser.add_argument("--steps", type=int, default=None, help="stop after this many steps")
    parser.add_argument("--run-root", default=None, help="where env_0/ is made")
    parser.add_argument("--solid", choices=sorted(SOLIDS), default="dealii")
    args = parser.parse_args(argv)
    env = PerpendicularFlapEnv(solid=args.solid, run_root=args.run_root)
    try:
        result = run_open_loop(env, args.frequency, args.steps)
    finally:
        env.close()
    tip = result["observation"][:, :2]
    print(
        f"{len(result['action'])} steps to t = {result['time'][-1]:.3f} s; "
        f"return {result['reward'].sum():.4f}; max |tip displacement| "
        f"{np.linalg.norm(tip, axis=1).max():.4f} m"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
