"""The copyable examples under examples/ pass `gymprecice check`, and the Python-solver one
runs episodes against the test double exactly as shipped."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from gymprecice.cli import main

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
CASES = sorted(p.parent for p in EXAMPLES.glob("*/gymprecice-config.json"))


def test_both_examples_are_there() -> None:
    assert {c.name for c in CASES} >= {"python-solver", "openfoam-channel"}


@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_example_passes_gymprecice_check(case: Path, capsys) -> None:
    assert main(["check", str(case)]) == 0, capsys.readouterr().err


def _load(path: Path):
    spec = importlib.util.spec_from_file_location(f"example_{path.parent.name}", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_python_solver_example_runs_against_the_double(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)  # run_root is relative to the working directory
    env = _load(EXAMPLES / "python-solver" / "env.py").HeatedRodEnv()
    try:
        obs, _ = env.reset(seed=0)
        assert obs.shape == (4,) and not obs.any()  # read data are zeros at reset
        for _ in range(3):
            obs, reward, terminated, truncated, info = env.step(np.full(3, 40.0, np.float32))
            assert obs.shape == (4,) and (obs > 0).all() and np.isfinite(reward)
            assert not terminated and not truncated
        assert info["time"] == pytest.approx(0.3)
    finally:
        env.close()
    assert (tmp_path / "gymprecice-runs" / "env_0").is_dir()


def test_openfoam_example_env_constructs(tmp_path: Path, monkeypatch) -> None:
    """Without OpenFOAM and preCICE it cannot run; it must at least load and build."""
    monkeypatch.chdir(tmp_path)
    env = _load(EXAMPLES / "openfoam-channel" / "env.py").ChannelEnv()
    try:
        assert env.action_space.shape == (1,) and env.observation_space.shape == (3,)
    finally:
        env.close()
