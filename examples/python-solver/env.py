"""The controller side of the example: a Gymnasium env on the heated rod.

Run it from this directory: ``python env.py`` (three episodes' worth of random actions
against gymprecice's test double; set both "library" entries of gymprecice-config.json to
"precice" for real preCICE).
"""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np

from gymprecice.core import Adapter

HERE = Path(__file__).resolve().parent


class HeatedRodEnv(Adapter):
    """Action: the heat of three heaters; observation: four temperatures; reward: track 0.05."""

    TARGET = 0.05

    def __init__(self, options: str | Path = HERE, idx: int = 0) -> None:
        super().__init__(options, idx)
        # A "command" solver has no geometry plugin: say where the controller's vertices
        # are, here in __init__, before the first reset. preCICE maps them to the rod's.
        self.set_interface_vertices(
            "heater", [[0.25, 0.0], [0.5, 0.0], [0.75, 0.0]]
        )
        self.set_interface_vertices(
            "sensor", [[0.1, 0.0], [0.4, 0.0], [0.6, 0.0], [0.9, 0.0]]
        )
        self.action_space = gym.spaces.Box(
            0.0, 50.0, shape=(3,), dtype=np.float32
        )
        self.observation_space = gym.spaces.Box(
            -np.inf, np.inf, shape=(4,), dtype=np.float32
        )
        self._temperature = np.zeros(4, dtype=np.float32)

    def _get_action(self, action, write_var_list):
        # keys: an interface name, "Data-interface" ("Heat-heater") or a DataRef
        return {"heater": np.asarray(action, dtype=float)}

    def _get_observation(self, read_data, read_var_list):
        # read_data["Temperature-sensor"] is the same array; zeros at reset(), since the
        # rod's exchange has no initialize="true"
        self._temperature = np.asarray(read_data["sensor"], dtype=np.float32)
        return self._temperature.copy()

    def _get_reward(self):
        return -float(np.abs(self._temperature - self.TARGET).mean())

    def _close_external_resources(self):
        pass


if __name__ == "__main__":
    env = HeatedRodEnv()
    try:
        obs, info = env.reset(seed=0)
        done = False
        while not done:
            obs, reward, terminated, truncated, info = env.step(
                env.action_space.sample()
            )
            done = terminated or truncated
            print(
                f"t={info['time']:.2f} T={np.round(obs, 4)} reward={reward:.4f}"
            )
    finally:
        env.close()
