"""HeatedPlateFast-v0, the heated plate's training case, without solvers: files, starts.

The real-stack episodes are in ``test_heated_plate_real.py``; here the training case's
edits are checked on its files and the env's start handling on the lumped-plate double.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from gymprecice.plugin.precice_xml import load_precice_config
from gymprecice_tutorials.heated_plate.environment import EVAL_STARTS, HeatedPlateEnv, case_files
from gymprecice_tutorials.heated_plate.fast import (
    FAST_WINDOW,
    HeatedPlateFastEnv,
    fast_case_files,
)


def test_the_training_case_is_the_packaged_case_with_a_coarse_explicit_flow(tmp_path) -> None:
    full, fast = case_files("openfoam", 2.3), fast_case_files(2.3)
    assert set(full) == set(fast)
    mesh = fast["fluid-openfoam/system/blockMeshDict"]
    cells = [tuple(map(int, m)) for m in re.findall(r"\) \((\d+) (\d+) 1\) simpleGrading", mesh)]
    assert cells == [(21, 11), (41, 11), (13, 11)]
    for rel in ("fluid-openfoam/system/controlDict", "solid-openfoam/system/controlDict"):
        assert f"deltaT          {FAST_WINDOW:g};" in fast[rel]
    xml = fast["precice-config.xml"]
    assert "<coupling-scheme:serial-implicit>" not in xml and "<acceleration" not in xml
    assert xml.count("<coupling-scheme:serial-explicit>") == 1
    assert set(re.findall(r'<time-window-size value="([^"]*)" />', xml)) == {"0.01"}
    assert set(re.findall(r'<max-time value="([^"]*)" />', xml)) == {"2.3"}
    assert fast["gymprecice-config.json"] == full["gymprecice-config.json"]
    # A longer window (measured, not used) spans fewer windows per action.
    longer = fast_case_files(2.3, window=0.05)
    assert '"windows": 2' in longer["gymprecice-config.json"]
    assert 'time-window-size value="0.05"' in longer["precice-config.xml"]
    # The Fluid-Solid exchanges survive the change of scheme.
    path = tmp_path / "precice-config.xml"
    path.write_text(xml)
    config = load_precice_config(path)
    assert config.participants  # parses, and names its participants
    for data in ("Temperature", "Heat-Flux"):
        assert f'<exchange data="{data}"' in xml


def test_the_training_case_refuses_a_window_that_does_not_divide_an_action() -> None:
    with pytest.raises(ValueError, match="window must divide"):
        fast_case_files(2.3, window=0.03)


def test_the_training_case_trains_on_the_openfoam_plate_only() -> None:
    with pytest.raises(ValueError, match=r"HeatedPlate-v0 \(solid='fenics'\)"):
        HeatedPlateFastEnv(solid="fenics", double=True)


@pytest.mark.parametrize("cls", [HeatedPlateEnv, HeatedPlateFastEnv])
def test_every_held_out_start_is_reachable_by_index_on_the_double(cls, tmp_path) -> None:
    env = cls(double=True, episode_time=0.3, settle_time=0.1, run_root=tmp_path)
    try:
        assert len(env.held_out_starts) == len(EVAL_STARTS) == 3
        for k, start in enumerate(EVAL_STARTS):
            _, info = env.reset(seed=0, options={"split": "eval", "start": k})
            assert env.start == start
            assert info["start"]["setpoint"] == start.setpoint
        steps, truncated = 0, False
        while not truncated:
            _, reward, terminated, truncated, info = env.step(np.array([320.0], np.float32))
            assert not terminated and reward < 0
            steps += 1
        assert steps == 3
        with pytest.raises(ValueError, match="3 held-out starts, use 0 to 2"):
            env.reset(options={"split": "eval", "start": 3})
    finally:
        env.close()
