"""The copyable examples under examples/ pass `gymprecice check`, and the Python-solver one
runs episodes against the test double exactly as shipped."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from gymprecice.tools.cli import main

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


def _real_precice_importable() -> bool:
    import subprocess
    import sys

    probe = subprocess.run([sys.executable, "-c", "import precice"], capture_output=True)
    return probe.returncode == 0


def _on_real_precice(example: str, tmp_path: Path) -> Path:
    """A copy of an example whose config (and solver command) use real pyprecice."""
    import json
    import shutil

    case = tmp_path / example
    shutil.copytree(EXAMPLES / example, case)
    config_path = case / "gymprecice-config.json"
    text = config_path.read_text().replace("gymprecice.testing.fake_precice", "precice")
    config_path.write_text(text)
    assert json.loads(text)["precice"]["library"] == "precice"
    return case


@pytest.mark.precice
@pytest.mark.skipif(not _real_precice_importable(), reason="pyprecice / preCICE not installed")
def test_python_solver_example_runs_on_real_precice(tmp_path: Path, monkeypatch) -> None:
    """Cost: about 1 s (the example's Python solver and the env, a few windows)."""
    case = _on_real_precice("python-solver", tmp_path)
    monkeypatch.chdir(tmp_path)
    env = _load(case / "env.py").HeatedRodEnv(case)
    try:
        obs, _ = env.reset(seed=0)
        assert not obs.any()
        for _ in range(3):
            obs, reward, terminated, truncated, info = env.step(np.full(3, 40.0, np.float32))
            assert (obs > 0).all() and np.isfinite(reward) and not (terminated or truncated)
        assert info["time"] == pytest.approx(0.3)
    finally:
        env.close()


@pytest.mark.precice
@pytest.mark.openfoam
@pytest.mark.slow
@pytest.mark.timeout(900)
def test_openfoam_example_runs_on_real_openfoam_and_precice(tmp_path: Path, monkeypatch) -> None:
    """Cost: about 3 s (blockMesh and a few pimpleFoam windows of the example's small case)."""
    from gymprecice.plugin.errors import CaseError
    from gymprecice_openfoam.installation import find_openfoam

    try:
        adapter = find_openfoam().find_library()
    except CaseError:
        adapter = None
    if adapter is None or not _real_precice_importable():
        pytest.skip("needs OpenFOAM, the OpenFOAM-preCICE adapter and pyprecice")
    case = _on_real_precice("openfoam-channel", tmp_path)
    monkeypatch.chdir(tmp_path)
    env = _load(case / "env.py").ChannelEnv(case)
    try:
        obs, _ = env.reset(seed=0)
        assert obs.shape == (3,) and not obs.any()  # no probe row at the start time
        seen = []
        for speed in (0.0, 0.2):
            obs, _, terminated, _, _ = env.step(np.array([speed], np.float32))
            assert np.isfinite(obs).all() and not terminated
            seen.append(obs.copy())
        # the inlet speed the controller wrote reached OpenFOAM: the pressures answered
        assert not np.allclose(seen[0], seen[1])
    finally:
        env.close()


# -- the training guides (docs/guides/): each script trains on the double and saves a policy
# that `gymprecice evaluate` loads. RLlib's (examples/rllib_ppo.py) runs in .venv-rllib and saves
# an RLlib checkpoint: tests/test_rllib.py runs it.


GUIDES = {
    "sb3_ppo.py": [],
    "cleanrl_ppo.py": [],
    "torchrl_ppo.py": [],
}


@pytest.mark.slow
@pytest.mark.timeout(600)
@pytest.mark.parametrize("script", sorted(GUIDES))
def test_training_guide_trains_on_the_double_and_evaluate_loads_its_policy(
    script: str, tmp_path: Path, monkeypatch
) -> None:
    import subprocess
    import sys

    if script.startswith("torchrl"):
        pytest.importorskip("torchrl", reason="TorchRL's guide needs torchrl (scripts/setup.sh)")
    out = tmp_path / "policy"
    proc = subprocess.run(
        [sys.executable, str(EXAMPLES / script), "--double", "--out", str(out), *GUIDES[script]],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=540,
    )
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert "320" in proc.stdout  # it ran the few hundred steps it was asked for
    assert (out / "model.zip").is_file()

    monkeypatch.chdir(tmp_path)
    argv = ["evaluate", "jet-cylinder-fast", "--double", "--policy", str(out)]
    assert main([*argv, "--episode-time", "0.25", "--out", str(tmp_path / "eval")]) == 0
    import json

    summary = json.loads((tmp_path / "eval" / "summary.json").read_text())
    assert len(summary["episodes"]) == 1 and np.isfinite(summary["mean_return"])
