"""RotatingCylinder-v0: drag reduction by rotating the cylinder.

The same Schäfer-Turek flow as the jet cylinder (Re = 100, dt = 5e-4 s, 50 solver steps
per action, 80 actions from a developed-shedding snapshot), but the whole cylinder wall
moves: the action is its angular velocity ``omega`` in rad/s (counter-clockwise positive),
written on every wall face as the tangential velocity ``omega x r`` by the OpenFOAM
plugin's rotating-wall actuator. Observation and reward are the jet cylinder's (151
pressure probes; ``reward_offset - <Cd> - lift_penalty |<Cl>|`` over one shedding
period). The lift penalty matters more here: steady rotation produces a steady lift (the
Magnus effect), which the penalty stops the agent from trading for drag.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np

from gymprecice.env.core import DataRef
from gymprecice.plugin.fields import Overlay
from gymprecice.plugin.solver import InterfaceGeometry
from gymprecice_openfoam import actuators
from gymprecice_tutorials.cylinder_geometry import patch_geometry
from gymprecice_tutorials.jet_cylinder.environment import CylinderFlowEnv

__all__ = ["MAX_OMEGA", "RotatingCylinderEnv"]

#: Largest angular velocity (rad/s): a wall speed ``omega R`` of 0.25 Umean, enough to
#: move the separation points without turning the wake into a steadily rotating one.
MAX_OMEGA = 5.0


class RotatingCylinderEnv(CylinderFlowEnv):
    """The cylinder rotates at ``omega`` rad/s; see :class:`JetCylinderEnv` for the kwargs.

    Own keyword argument: ``max_omega`` (the action bound, default :data:`MAX_OMEGA`).
    ``jet_width`` does not apply (the rotating case has no jets).
    """

    recipe: ClassVar[str] = "rotating_cylinder"

    def __init__(
        self,
        options: Mapping[str, Any] | str | Path | None = None,
        idx: int = 0,
        *,
        max_omega: float = MAX_OMEGA,
        **kwargs: Any,
    ) -> None:
        if max_omega <= 0:
            raise ValueError(f"max_omega must be positive, got {max_omega}")
        super().__init__(options, idx, **kwargs)
        self.max_omega = float(max_omega)
        self.action_space = gym.spaces.Box(
            -self.max_omega, self.max_omega, shape=(1,), dtype=np.float32
        )

    def _analytic_geometry(self) -> dict[str, InterfaceGeometry]:
        return {"cylinder": patch_geometry(self.case_spec, "cylinder")}

    def _render_overlay(self) -> Overlay:
        """The spin, as text and as the wall's velocity at the top and bottom of the cylinder."""
        omega = float(np.asarray(self.last_action, dtype=float).ravel()[0])
        g = self.case_spec.geometry
        (cx, cy), r = g.centre, g.radius
        length = 1.5 * g.diameter * omega / self.max_omega  # counter-clockwise: left on top
        return Overlay(
            text=[f"spin ω = {omega:+.3f} rad/s ({'counter-' if omega >= 0 else ''}clockwise)"],
            arrows=[(cx, cy + r, -length, 0.0), (cx, cy - r, length, 0.0)],
        )

    def _get_action(self, action: Any, write_var_list: list[DataRef]) -> dict[str, np.ndarray]:
        omega = float(self._clip(action)[0])
        g = self.case_spec.geometry
        return {
            "cylinder": actuators.rotating_wall_velocity(
                self.geometry_of("cylinder"), omega, centre=(g.centre[0], g.centre[1], 0.0)
            )
        }
