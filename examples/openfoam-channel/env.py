"""The controller side of the OpenFOAM example: the inlet speed of a channel.

Needs OpenFOAM, preCICE and the OpenFOAM-preCICE adapter (``gymprecice doctor``); check the
case without them with ``gymprecice check .``. Run from this directory: ``python env.py``.
"""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np

from gymprecice.core import Adapter

HERE = Path(__file__).resolve().parent


class ChannelEnv(Adapter):
    """Action: inlet speed (m/s); observation: pressure at three probes; reward: hold 0.1 m/s."""

    def __init__(self, options: str | Path = HERE, idx: int = 0) -> None:
        # The OpenFOAM plugin knows the inlet's face centres, normals and areas (from the
        # preciceDict interface that uses the partner mesh): no set_interface_vertices.
        super().__init__(options, idx)
        self.action_space = gym.spaces.Box(
            0.0, 0.2, shape=(1,), dtype=np.float32
        )
        self.observation_space = gym.spaces.Box(
            -np.inf, np.inf, shape=(3,), dtype=np.float32
        )
        self._speed = 0.0

    def _get_action(self, action, write_var_list):
        inlet = self.interface_geometry["inlet"]
        self._speed = float(action[0])
        # inward: minus the outward face normals, x and y only (2-D meshes)
        return {"inlet": -self._speed * inlet.normals[:, :2]}

    def _get_observation(self, read_data, read_var_list):
        probes = self.open_output("fluid", "probes", field="p")
        if self.time == 0.0:
            # OpenFOAM writes no probe row at the start time: nothing to wait for at reset
            return np.zeros(3, dtype=np.float32)
        # start_time: the solver time the episode starts from (here the pre-run's end, 1.0)
        t = (probes.start_time or 0.0) + self.time
        return probes.wait_until(t, timeout=120).last.astype(np.float32)

    def _get_reward(self):
        return -abs(self._speed - 0.1)

    def _close_external_resources(self):
        pass


if __name__ == "__main__":
    env = ChannelEnv()
    try:
        obs, info = env.reset(seed=0)
        for _ in range(5):
            obs, reward, terminated, truncated, info = env.step(
                np.array([0.15], np.float32)
            )
            print(f"t={info['time']:.2f} p={obs} reward={reward:.3f}")
    finally:
        env.close()
