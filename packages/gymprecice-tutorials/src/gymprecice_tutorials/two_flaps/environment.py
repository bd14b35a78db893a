"""PettingZoo environment of two flaps in one channel: each flap's floor slot is one agent.

Task: two elastic flaps stand one behind the other in a channel with a uniform inflow.
In the floor, 0.2 m in front of each flap, is a slot 0.2 m wide that blows fluid into the
channel or sucks it out, normal to the floor. Each agent drives its own slot and should
keep its own flap still.

Why a slot in front of the flap: the flow pushes a flap by the pressure on its upstream
face. A slot just ahead of it changes how much near-floor fluid meets the flap: blowing
adds fluid that has to pass over the flap and pushes it further, suction draws fluid out
of the floor layer and eases the push (on the training case, full blowing at 10 m/s
raises the upstream flap's first swing from 0.035 m to 0.044 m, full suction lowers it to
0.031 m). So each agent modulates the load on its own flap, as the single flap's moving
inlet jet does, but locally: the upstream slot acts 2 m ahead of the downstream flap,
which feels it mainly through the upstream flap's wake.

* **Agents**: ``"upstream"`` (the flap at x = -1, slot ``upstream_jet``) and
  ``"downstream"`` (the flap at x = 1, slot ``downstream_jet``).
* **Action** ``(1,)`` per agent, in ``[-1, 1]``: the slot's mean velocity as a fraction of
  ``jet_max_velocity`` (default 10 m/s, twice the inflow's speed: a tenth of the
  channel's flow rate through the slot); positive blows into the channel, negative sucks.
  The profile across the slot is a parabola whose discrete flow rate is exactly
  ``action * jet_max_velocity * 0.2`` m²/s per metre of depth.
* **Observation** ``(9,)`` per agent: its own flap's tip displacement ``(dx, dy)``, tip
  velocity ``(vx, vy)`` over the last time window and the stress at the tip ``(sx, sy)``,
  from its solid's preCICE watch point ``Flap-Tip``; what it senses nearby: the other
  flap's tip ``dx`` and ``vx``; and which flap it is (+1 upstream, -1 downstream), so one
  shared policy can act differently for the two.
* **Reward** per agent: ``-mean |d|`` of its own tip over the time windows of the step
  (metres), as the single flap.
* **Episode end**: every agent truncated at the coupling's ``max-time``; no terminal state.
* **Rendering** (``render_mode="rgb_array"``): the fluid's speed and both flaps, bent by
  their solids' displacement, in one frame; each slot's setting as an arrow (blowing up
  out of the floor, suction down into it, its length the slot's mean velocity) and as text.

The observations wait for each solid's watch-point row of the current time
(``watch_timeout`` seconds at most), which keeps the env in step with the physics: the
controller only writes, so preCICE's ``advance`` does not hold it back while fluid and
solids iterate a window.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np

from gymprecice.multiagent import MultiAgentAdapter
from gymprecice.plugin.fields import Overlay
from gymprecice_tutorials.perpendicular_flap.environment import jet_profile
from gymprecice_tutorials.two_flaps import CASE_DIR

__all__ = ["FLAPS", "JET_WIDTH", "Flap", "TwoFlapsEnv", "slot_velocity"]

CONFIG_FILE = CASE_DIR / "gymprecice-config.json"
#: width (m) of each floor slot
JET_WIDTH = 0.2
#: length (m) of a slot's arrow in a frame per m/s of its mean velocity (10 m/s: 0.5 m,
#: half a flap's height)
ARROW_PER_VELOCITY = 0.05


@dataclass(frozen=True)
class Flap:
    """One flap and its agent: the solver, the preCICE names and its slot."""

    agent: str
    solver: str
    participant: str
    jet: str
    #: x (m) of the flap's centre and of its slot's centre
    x: float
    jet_x: float
    #: +1 upstream, -1 downstream: the last entry of the agent's observation
    flag: float

    @property
    def displacement(self) -> str:
        return f"Displacement-{self.participant.split('-')[-1]}"

    @property
    def stress(self) -> str:
        return f"Stress-{self.participant.split('-')[-1]}"


FLAPS: tuple[Flap, ...] = (
    Flap("upstream", "upstream", "Solid-Upstream", "upstream_jet", -1.0, -1.35, 1.0),
    Flap("downstream", "downstream", "Solid-Downstream", "downstream_jet", 1.0, 0.65, -1.0),
)


def slot_velocity(x: np.ndarray, centre: float, mean_velocity: float, areas: Any = None) -> Any:
    """Velocity ``(n, 2)`` of a slot's faces at ``x``: a parabola blowing along +y.

    The discrete flow rate ``sum(v * areas)`` is ``mean_velocity * sum(areas)`` on any
    mesh (:func:`~gymprecice_tutorials.perpendicular_flap.environment.jet_profile`);
    a negative ``mean_velocity`` sucks.
    """
    x = np.asarray(x, dtype=float)
    if mean_velocity == 0.0:
        return np.zeros((len(x), 2))
    sign = 1.0 if mean_velocity > 0 else -1.0
    v = sign * jet_profile(x, centre, JET_WIDTH, abs(mean_velocity), areas=areas)
    return np.column_stack([np.zeros_like(v), v])


class TwoFlapsEnv(MultiAgentAdapter):
    """Two flaps, two slots, two agents (see the module docstring)."""

    agent_data: ClassVar[dict[str, list[str]]] = {flap.agent: [flap.jet] for flap in FLAPS}
    #: the watch point both solids declare in ``precice-config.xml``
    WATCH_POINT = "Flap-Tip"
    #: ``render_mode="rgb_array"``: the fluid and both bent flaps, one frame per action
    #: (0.1 s of flow)
    metadata: ClassVar[dict[str, Any]] = {
        "name": "two_flaps",
        "render_modes": ["rgb_array"],
        "render_fps": 10,
    }

    def __init__(
        self,
        options: Mapping[str, Any] | str | Path | None = None,
        idx: int | None = 0,
        *,
        jet_max_velocity: float = 10.0,
        watch_timeout: float = 120.0,
        **kwargs: Any,
    ) -> None:
        super().__init__(CONFIG_FILE if options is None else options, idx, **kwargs)
        if not jet_max_velocity > 0:
            raise ValueError(f"jet_max_velocity must be positive, got {jet_max_velocity}")
        self.jet_max_velocity = float(jet_max_velocity)
        self.watch_timeout = float(watch_timeout)
        self.flaps = {flap.agent: flap for flap in FLAPS}
        self.action_spaces = {
            agent: gym.spaces.Box(-1.0, 1.0, shape=(1,), dtype=np.float32)
            for agent in self.possible_agents
        }
        self.observation_spaces = {
            agent: gym.spaces.Box(-np.inf, np.inf, shape=(9,), dtype=np.float32)
            for agent in self.possible_agents
        }
        self._tips: dict[str, Any] = {}
        self._step_rows: dict[str, np.ndarray] = {}
        #: each agent's slot mean velocity (m/s) in the last window written
        self.jet_velocity = dict.fromkeys(self.possible_agents, 0.0)
        #: each flap's tip ``(dx, dy, vx, vy, sx, sy)`` at the last observation
        self.tip_state: dict[str, np.ndarray] = {}

    # -- rendering ---------------------------------------------------------------------------
    @property
    def render_fields(self) -> dict[str, tuple[str, ...]]:  # type: ignore[override]
        """The fluid's speed, then each flap's displacement, drawn on the bent flap.

        On the real case the fluid's ``U`` comes from OpenFOAM and each solid's
        ``displacement`` from its deal.II adapter's snapshots; on the test double the
        upstream scripted flap hands over a stand-in fluid and both hand over their flap.
        """
        flaps = {flap.solver: ("displacement",) for flap in FLAPS}
        if "fluid" in self.config.solvers:
            return {"fluid": ("U",), **flaps}
        first = FLAPS[0].solver
        return {first: ("U", "displacement"), **{k: v for k, v in flaps.items() if k != first}}

    def _render_overlay(self) -> Overlay:
        """Each slot's setting: an arrow out of (blowing) or into (suction) the floor at
        the slot, its length the slot's mean velocity, and a line of text per slot."""
        arrows, text = [], []
        for flap in FLAPS:
            velocity = self.jet_velocity[flap.agent]
            length = ARROW_PER_VELOCITY * velocity
            if velocity > 0:
                arrows.append((flap.jet_x, 0.0, 0.0, length))
            elif velocity < 0:
                arrows.append((flap.jet_x, -length, 0.0, length))
            what = "blowing" if velocity > 0 else "suction" if velocity < 0 else "closed"
            text.append(f"{flap.agent:>10} slot {velocity:+5.1f} m/s {what}")
        return Overlay(text=text, arrows=arrows)

    # -- the user methods --------------------------------------------------------------------
    def _get_agent_action(self, agent: str, action: np.ndarray, write_var_list: list) -> dict:
        flap = self.flaps[agent]
        velocity = self._slot_mean_velocity(agent, action)
        self.jet_velocity[agent] = velocity
        geometry = self.interface_geometry[flap.jet]
        values = slot_velocity(geometry.coordinates[:, 0], flap.jet_x, velocity, geometry.areas)
        return {ref: values for ref in write_var_list}

    def _slot_mean_velocity(self, agent: str, action: np.ndarray) -> float:
        """The slot's mean velocity (m/s) an action asks for, clipped to the action space."""
        value = float(np.clip(np.asarray(action, dtype=float).reshape(-1)[0], -1.0, 1.0))
        return value * self.jet_max_velocity

    def _get_observations(self, read_data: Any, read_var_list: list) -> dict[str, np.ndarray]:
        state = {}
        for flap in FLAPS:
            tip = self._tips.get(flap.agent)
            if tip is None:  # core closes readers at every reset: open them per episode
                tip = self._tips[flap.agent] = self.open_output(
                    flap.solver, "watchpoint", point=self.WATCH_POINT
                )
            self._step_rows[flap.agent] = tip.wait_until(self.time, self.watch_timeout)
            state[flap.agent] = self._tip_state(flap, tip)
        self.tip_state = state
        obs = {}
        for flap in FLAPS:
            if flap.agent not in self.agents:
                continue
            other = next(f for f in FLAPS if f is not flap)
            own, near = state[flap.agent], state[other.agent]
            obs[flap.agent] = np.concatenate([own, near[[0, 2]], [flap.flag]]).astype(np.float32)
        return obs

    def _tip_state(self, flap: Flap, tip: Any) -> np.ndarray:
        """``(dx, dy, vx, vy, sx, sy)`` of a tip from its watch point's last two rows."""
        rows = tip.data[-2:]
        displacement = tip.field(flap.displacement, rows)
        stress = tip.field(flap.stress, rows[-1:])[0]
        if len(rows) == 2 and rows[1, 0] > rows[0, 0]:
            velocity = (displacement[1] - displacement[0]) / (rows[1, 0] - rows[0, 0])
        else:
            velocity = np.zeros(2)
        return np.concatenate([displacement[-1], velocity, stress])

    def _get_rewards(self) -> dict[str, float]:
        return {agent: -self.mean_tip_displacement(agent) for agent in self.agents}

    def mean_tip_displacement(self, agent: str) -> float:
        """Mean ``|d|`` (m) of ``agent``'s tip over the windows of the last step."""
        flap = self.flaps[agent]
        tip = self._tips[agent]
        rows = self._step_rows.get(agent)
        if rows is None or not len(rows):
            rows = tip.data[-1:]
        return float(np.mean(np.linalg.norm(tip.field(flap.displacement, rows), axis=1)))

    def _close_external_resources(self) -> None:
        self._tips = {}
        self._step_rows = {}

    def step(self, actions: Mapping[str, Any]) -> Any:
        """The multi-agent step, plus each agent's slot velocity and tip metrics in its info.

        ``info[agent]["metrics"]`` holds the tip displacement at the step's end
        (``tip_dx``, ``tip_dy``) and its mean magnitude over the step
        (``mean_tip_displacement``, the negated reward); ``info[agent]["action"]`` the
        slot's mean velocity (m/s).
        """
        obs, rewards, terms, truncs, infos = super().step(actions)
        for agent, info in infos.items():
            if "diverged" in info:
                continue
            info["action"] = [self.jet_velocity[agent]]
            info["metrics"] = {
                "tip_dx": float(obs[agent][0]),
                "tip_dy": float(obs[agent][1]),
                "mean_tip_displacement": -float(rewards[agent]),
            }
        return obs, rewards, terms, truncs, infos
