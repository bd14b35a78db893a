"""A resumed training's Monitor file: its columns follow the run that appends to it."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("stable_baselines3")


class _OneStep(gym.Env):
    """An episode of one step whose info holds ``keys``."""

    observation_space = gym.spaces.Box(-1.0, 1.0, (1,), np.float32)
    action_space = gym.spaces.Box(-1.0, 1.0, (1,), np.float32)

    def __init__(self, keys: dict[str, float]) -> None:
        self.keys = keys

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        return np.zeros(1, np.float32), {}

    def step(self, action):
        return np.zeros(1, np.float32), 2.0, False, True, dict(self.keys)


def _rows(path: Path) -> tuple[str, list[dict[str, str]]]:
    with path.open(newline="") as handle:
        header = handle.readline()
        return header, list(csv.DictReader(handle))


def test_a_run_resumed_with_other_columns_rewrites_them_and_keeps_every_value(tmp_path):
    from gymprecice_lab.common.wrapped_env import _monitor

    path = tmp_path / "env_0.monitor.csv"
    header = "#" + json.dumps({"t_start": 1000.0, "env_id": "x"}) + "\n"
    path.write_text(header + "r,l,t,old_metric,mean_Cd\n1.0,1,0.5,7.0,3.2\n")
    env = _monitor(
        _OneStep({"mean_Cd": 3.1, "new_metric": 9.0}),
        str(tmp_path / "env_0"),
        ("mean_Cd", "new_metric"),
    )
    env.reset()
    env.step(np.zeros(1, np.float32))
    env.close()
    first, rows = _rows(path)
    assert first == header  # the first run's clock, so that t keeps increasing
    old, new = rows
    assert (old["r"], old["old_metric"], old["mean_Cd"], old["new_metric"]) == (
        "1.0",
        "7.0",
        "3.2",
        "",
    )
    assert (new["r"], new["mean_Cd"], new["new_metric"]) == ("2.0", "3.1", "9.0")
    assert new["old_metric"] in ("", None)
    assert float(new["t"]) > 0


def test_a_run_resumed_with_the_same_columns_appends_unchanged(tmp_path):
    from gymprecice_lab.common.wrapped_env import _monitor

    path = tmp_path / "env_0.monitor.csv"
    text = "#" + json.dumps({"t_start": 1000.0}) + "\nr,l,t,mean_Cd\n1.0,1,0.5,3.2\n"
    path.write_text(text)
    env = _monitor(_OneStep({"mean_Cd": 3.1}), str(tmp_path / "env_0"), ("mean_Cd",))
    env.reset()
    env.step(np.zeros(1, np.float32))
    env.close()
    assert path.read_text().startswith(text)
    assert [r["mean_Cd"] for r in _rows(path)[1]] == ["3.2", "3.1"]
