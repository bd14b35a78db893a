"""A diverging solver ends the episode as an outcome; a fault stays a fault.

Runs the chaos case (Adapter, coupling worker, the preCICE double, a solver process) whose
solver diverges on request (:func:`gymprecice.testing.chaos.inject` ``"diverge"``): its
log shows a ``Floating point exception`` (the case's ``divergence_patterns``) and it exits
with status 136. The step must terminate with the penalty and ``info["diverged"]``, the
vector env must not count a failure, and a kill in the same run must still be one.
"""

from __future__ import annotations

import functools
import json
import math
import sys

import numpy as np
import pytest

from gymprecice.env.core import LIBRARY_ENV_VAR, NonFiniteValueError
from gymprecice.plugin.errors import ConfigError, SolverCrashedError
from gymprecice.testing.chaos import CylinderEnv, inject, write_case
from gymprecice.vector import ResilientVectorEnv

pytestmark = pytest.mark.skipif(
    not sys.platform.startswith("linux"), reason="the chaos case's solver runs on Linux"
)

PENALTY = -42.0


@pytest.fixture
def case(tmp_path, monkeypatch):
    monkeypatch.setenv("GYMPRECICE_DISABLE_PLUGINS", "1")
    monkeypatch.delenv(LIBRARY_ENV_VAR, raising=False)
    root = write_case(
        tmp_path / "case",
        tmp_path / "faults",
        end_time=0.1,
        window=0.01,
        windows_per_step=2,
        timeouts={"progress": 4, "reset": 30, "kill_grace": 0.5},
    )
    config = json.loads((root / "gymprecice-config.json").read_text())
    config["environment"]["divergence_penalty"] = PENALTY
    (root / "gymprecice-config.json").write_text(json.dumps(config))
    return root


def _edit(case, edit) -> None:
    path = case / "gymprecice-config.json"
    config = json.loads(path.read_text())
    edit(config)
    path.write_text(json.dumps(config))


def test_divergence_terminates_with_the_penalty_and_the_next_episode_works(case, tmp_path):
    inject(tmp_path / "faults", 0, "run", "diverge", window=3)
    env = CylinderEnv(str(case), 0, run_root=str(tmp_path / "runs"))
    try:
        first, _ = env.reset(seed=0)
        obs, reward, terminated, truncated, info = env.step(np.array([0.5], dtype=np.float32))
        assert not terminated and not truncated
        obs, reward, terminated, truncated, info = env.step(np.array([0.5], dtype=np.float32))
        assert (terminated, truncated, reward) == (True, False, PENALTY)
        diverged = info["diverged"]
        assert diverged["solver"] == "fluid"
        assert diverged["time"] == pytest.approx(0.02)  # the step began at window 2
        assert "Floating point exception" in diverged["evidence"]
        assert obs.shape == first.shape and np.all(np.isfinite(obs))
        # the next episode starts clean and runs to its end
        env.reset()
        truncated = False
        steps = 0
        while not truncated:
            _, _, terminated, truncated, info = env.step(np.array([0.5], dtype=np.float32))
            assert not terminated and "diverged" not in info
            steps += 1
        assert steps == 5
    finally:
        env.close()


def test_divergence_is_not_a_failure_but_a_kill_in_the_same_run_is(case, tmp_path):
    faults = tmp_path / "faults"
    inject(faults, 0, "run", "diverge", window=3)
    inject(faults, 1, "run", "kill", window=3)
    fns = [
        functools.partial(CylinderEnv, str(case), i, run_root=str(tmp_path / "runs"))
        for i in range(2)
    ]
    venv = ResilientVectorEnv(
        fns, step_timeout=8, reset_timeout=60, kill_grace=0.5, close_timeout=10
    )
    try:
        venv.reset(seed=0)
        act = np.full((2, 1), 0.3, dtype=np.float32)
        venv.step(act)
        _, rewards, terms, truncs, infos = venv.step(act)
        assert terms.tolist() == [True, False]
        assert truncs.tolist() == [False, True]  # the kill: a failure, reported as truncation
        assert rewards[0] == PENALTY
        final = infos["final_info"]  # same-step autoreset: the ended episode's info
        assert final["_diverged"].tolist() == [True, False]
        assert final["diverged"]["solver"][0] == "fluid"
        assert [f.env_index for f in venv.failures] == [1]
        counted = venv.pool.telemetry.drain()  # what the training log records
        assert (counted["divergences"], counted["failures"]) == (1.0, 1.0)
        assert "1 failures, 1 divergences" in venv.pool.telemetry.summary()
        assert venv.failures[0].type.endswith("SolverCrashedError")
        # both go on: env 0 autoresets clean, env 1 was respawned
        for _ in range(3):
            _, _, terms, truncs, infos = venv.step(act)
            assert "failure" not in infos
        assert len(venv.failures) == 1
    finally:
        venv.close()


def test_a_running_solver_is_watched_and_stopped_when_its_log_shows_divergence(case, tmp_path):
    """The watch sees a solver that is still running (no crash needed).

    The pattern is the solver's "window 3" line: it prints it before it sends window 4's
    data, which the second step waits for, and after window 3's data, which only the
    second step sends. So the line is in the log at the end of step 2 and not of step 1,
    however loaded the machine. (Its "window 4" line may come after step 2 returned.)
    """
    _edit(
        case,
        lambda c: c["physics_simulation_engine"]["solvers"]["fluid"]["options"].update(
            divergence_patterns=[r"window 3 "]
        ),
    )
    env = CylinderEnv(str(case), 0, run_root=str(tmp_path / "runs"))
    try:
        env.reset(seed=0)
        outcomes = [env.step(np.array([0.0], dtype=np.float32)) for _ in range(2)]
        assert [o[2] for o in outcomes] == [False, True]
        assert "window 3" in outcomes[1][4]["diverged"]["evidence"]
        assert outcomes[1][1] == PENALTY
        env.reset()  # and nothing is left of the stopped episode to get in the way
        assert not env.step(np.array([0.0], dtype=np.float32))[2]
    finally:
        env.close()


def test_a_killed_solver_stays_a_fault_even_with_divergence_patterns(case, tmp_path):
    inject(tmp_path / "faults", 0, "run", "kill", window=3)
    env = CylinderEnv(str(case), 0, run_root=str(tmp_path / "runs"))
    try:
        env.reset(seed=0)
        env.step(np.array([0.0], dtype=np.float32))
        with pytest.raises(SolverCrashedError):
            env.step(np.array([0.0], dtype=np.float32))
    finally:
        env.close()


@pytest.mark.parametrize("value", [math.nan, math.inf, "-10", True])
def test_a_penalty_that_is_not_a_finite_number_is_refused_with_the_key(case, tmp_path, value):
    config = json.loads((case / "gymprecice-config.json").read_text())
    config["environment"]["divergence_penalty"] = value
    with pytest.raises(ConfigError, match="divergence_penalty"):
        CylinderEnv(config, 0, run_root=str(tmp_path / "runs"), case_dir=case)


def test_a_bad_class_default_penalty_is_refused_with_the_fix(case, tmp_path):
    _edit(case, lambda c: c["environment"].pop("divergence_penalty"))

    class Careless(CylinderEnv):
        divergence_penalty = float("nan")

    with pytest.raises(ConfigError, match=r"Careless: divergence_penalty is nan.*finite number"):
        Careless(str(case), 0, run_root=str(tmp_path / "runs"))


def test_a_bad_divergence_pattern_is_refused_with_the_key(case, tmp_path):
    _edit(
        case,
        lambda c: c["physics_simulation_engine"]["solvers"]["fluid"]["options"].update(
            divergence_patterns=["(unclosed"]
        ),
    )
    with pytest.raises(ConfigError, match=r"options.divergence_patterns holds '\(unclosed'"):
        CylinderEnv(str(case), 0, run_root=str(tmp_path / "runs"))


def test_a_non_finite_observation_or_reward_never_reaches_the_learner(case, tmp_path):
    class NanReward(CylinderEnv):
        def _get_reward(self) -> float:
            return math.nan if self.time > 0.03 else 0.0

    class InfObservation(CylinderEnv):
        def _get_observation(self, read_data, read_var_list):
            obs = super()._get_observation(read_data, read_var_list)
            return obs * np.inf if self.time > 0 else obs

    env = NanReward(str(case), 0, run_root=str(tmp_path / "runs"))
    try:
        env.reset(seed=0)
        env.step(np.array([0.0], dtype=np.float32))
        with pytest.raises(NonFiniteValueError, match=r"_get_reward\(\) .* at step 2"):
            env.step(np.array([0.0], dtype=np.float32))
    finally:
        env.close()
    env = InfObservation(str(case), 0, run_root=str(tmp_path / "runs"))
    try:
        env.reset(seed=0)
        with pytest.raises(NonFiniteValueError, match=r"_get_observation\(\) .* at step 1"):
            env.step(np.array([0.0], dtype=np.float32))
    finally:
        env.close()
