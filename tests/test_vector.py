"""The fault-tolerant vector env with plain Gymnasium envs that sleep, raise, crash or hang.

These envs need no preCICE: they exercise the pool's own machinery (deadlines, respawn,
picklable failures, failure budget, autoreset, seeds and options, facades, telemetry).
Faults fire once per marker file, so a respawned env (rebuilt from the same ``env_fn``)
behaves normally afterwards.
"""

from __future__ import annotations

import functools
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import cloudpickle
import gymnasium as gym
import numpy as np
import pytest

from gymprecice.env.processes import PidRegistry
from gymprecice.plugin.errors import ConfigError
from gymprecice.vector import (
    EnvFailure,
    EnvPool,
    FailureBudgetExceededError,
    ResilientVectorEnv,
    describe_exception,
)
from gymprecice.vector.telemetry import Telemetry

# The envs below are defined here; workers get them by value.
cloudpickle.register_pickle_by_value(sys.modules[__name__])

EPISODE = 4
STEP_FAULTS = {"raise", "unpicklable", "kill", "exit", "hang", "bad-reply"}


class Unpicklable(Exception):
    """An exception that cannot cross a pipe (holds a lock)."""

    def __init__(self, message):
        super().__init__(message)
        self.lock = threading.Lock()


def _fire_once(marker: str | None) -> bool:
    """True the first time only (across processes): the fault fires once."""
    if not marker:
        return False
    try:
        os.close(os.open(marker, os.O_CREAT | os.O_EXCL | os.O_WRONLY))
    except FileExistsError:
        return False
    return True


class ScriptedEnv(gym.Env):
    """Observation ``[index, t, seed-marker]``; faults at step ``at`` of an episode.

    ``fault`` is one of ``raise``, ``unpicklable``, ``kill`` (SIGKILL itself), ``exit``,
    ``hang``, ``reset-raise``, ``reset-hang``, ``bad-reply`` (an info that cannot be
    pickled), ``always-reset-raise``, ``config-error`` (at construction), and fires once
    per ``marker`` file (always, for the ``always-`` faults).
    """

    metadata = {"render_modes": []}

    def __init__(
        self,
        index: int,
        fault: str | None = None,
        at: int = 2,
        marker: str | None = None,
        step_sleep: float = 0.0,
        reset_sleep: float = 0.0,
        build_sleep: float = 0.0,
        run_dir: str | None = None,
    ):
        if fault == "config-error":
            raise ConfigError(f"env {index}: gymprecice-config.json: bad key (test)")
        time.sleep(build_sleep)
        self.index, self.fault, self.at, self.marker = index, fault, at, marker
        self.step_sleep, self.reset_sleep = step_sleep, reset_sleep
        self.run_dir = run_dir
        self.observation_space = gym.spaces.Box(-1e9, 1e9, (3,), np.float64)
        self.action_space = gym.spaces.Box(-1.0, 1.0, (1,), np.float32)
        self.t = 0
        self.last_options = None
        self.draw = 0.0
        self.flag = "unset"

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        time.sleep(self.reset_sleep)
        if self.fault == "always-reset-raise":
            raise RuntimeError(f"env {self.index}: the case is broken (test)")
        if self.fault == "reset-raise" and _fire_once(self.marker):
            raise RuntimeError(f"env {self.index}: missing patch 'inlet' (test)")
        if self.fault == "reset-hang" and _fire_once(self.marker):
            time.sleep(1000)
        self.t = 0
        self.last_options = options
        self.draw = float(self.np_random.random())
        return self._obs(), {"options": dict(options or {}), "draw": self.draw}

    def _obs(self):
        return np.array([self.index, self.t, self.draw])

    def step(self, action):
        self.t += 1
        time.sleep(self.step_sleep)
        if self.t == self.at and self.fault in STEP_FAULTS and _fire_once(self.marker):
            if self.fault == "raise":
                raise ValueError(f"env {self.index}: solver diverged (test)")
            if self.fault == "unpicklable":
                raise Unpicklable(f"env {self.index}: exception with a lock (test)")
            if self.fault == "kill":
                os.kill(os.getpid(), signal.SIGKILL)
            if self.fault == "exit":
                print("about to exit hard (test)", file=sys.stderr, flush=True)
                os._exit(3)
            if self.fault == "hang":
                time.sleep(1000)
            if self.fault == "bad-reply":
                return self._obs(), 1.0, False, False, {"callback": threading.Lock()}
        done = self.t >= EPISODE
        return self._obs(), 1.0, False, done, {"t": self.t, "action": float(action[0])}

    def whoami(self, suffix=""):
        return f"env-{self.index}{suffix}"

    def broken(self):
        raise KeyError("no such thing (test)")

    def imported(self, module):
        return module in sys.modules

    def crash_once(self, marker):
        if _fire_once(marker):
            os.kill(os.getpid(), signal.SIGKILL)
        return f"env-{self.index} alive"


def time_limited(index):
    return gym.wrappers.TimeLimit(ScriptedEnv(index), max_episode_steps=100)


def fns(n, tmp_path, faults=None, **kwargs):
    faults = faults or {}
    return [
        functools.partial(
            ScriptedEnv,
            i,
            faults.get(i),
            marker=str(tmp_path / f"fault-{i}") if i in faults else None,
            **kwargs,
        )
        for i in range(n)
    ]


def alive(pid: int | None) -> bool:
    if pid is None:
        return False
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] not in ("Z", "X")
    except FileNotFoundError:
        return False


@pytest.fixture
def make_vec(tmp_path):
    made = []

    def make(env_fns, cls=ResilientVectorEnv, **kwargs):
        kwargs.setdefault("log_dir", tmp_path / "logs")
        kwargs.setdefault("step_timeout", 10)
        kwargs.setdefault("reset_timeout", 10)
        env = cls(env_fns, **kwargs)
        made.append(env)
        return env

    yield make
    for env in made:
        env.close()


# -- semantics -------------------------------------------------------------------------------


def test_reset_seeds_each_env_with_seed_plus_index_and_passes_options(make_vec, tmp_path):
    venv = make_vec(fns(3, tmp_path))
    obs, infos = venv.reset(seed=7, options={"split": "eval"})
    expected = [float(np.random.default_rng(7 + i).random()) for i in range(3)]
    # gymnasium seeds np_random with seed+i; the draw is its first number
    draws = [gym.utils.seeding.np_random(7 + i)[0].random() for i in range(3)]
    assert np.allclose(obs[:, 2], draws)
    assert np.allclose(infos["draw"], draws) and not np.allclose(draws, expected[::-1])
    assert list(infos["options"]["split"]) == ["eval"] * 3
    assert venv.metadata["autoreset_mode"] == gym.vector.AutoresetMode.SAME_STEP
    again, _ = venv.reset(seed=7)
    assert np.array_equal(obs, again)


def test_same_step_autoreset_keeps_final_obs_and_the_options(make_vec, tmp_path):
    venv = make_vec(fns(2, tmp_path))
    venv.reset(seed=0, options={"split": "eval"})
    for t in range(1, EPISODE):
        obs, rewards, terms, truncs, infos = venv.step(np.zeros((2, 1), np.float32))
        assert list(obs[:, 1]) == [t, t] and not truncs.any()
    obs, rewards, terms, truncs, infos = venv.step(np.full((2, 1), 0.5, np.float32))
    assert truncs.all() and not terms.any() and list(rewards) == [1.0, 1.0]
    assert list(obs[:, 1]) == [0, 0]  # already the next episode
    assert [o[1] for o in infos["final_obs"]] == [EPISODE, EPISODE]
    assert list(infos["final_info"]["t"]) == [EPISODE, EPISODE]
    # options stay in force for automatic resets
    assert list(infos["options"]["split"]) == ["eval", "eval"]
    assert venv.get_attr("last_options") == ({"split": "eval"}, {"split": "eval"})


def test_reset_mask_resets_only_some_envs(make_vec, tmp_path):
    venv = make_vec(fns(3, tmp_path))
    venv.reset(seed=1)
    venv.step(np.zeros((3, 1), np.float32))
    obs, infos = venv.reset(options={"reset_mask": np.array([False, True, False])})
    assert list(obs[:, 1]) == [1, 0, 1]
    assert list(infos["_draw"]) == [False, True, False]


def test_call_get_attr_set_attr_and_errors_of_methods(make_vec, tmp_path):
    venv = make_vec(fns(2, tmp_path))
    assert venv.call("whoami", suffix="!") == ("env-0!", "env-1!")
    assert venv.get_attr("index") == (0, 1)
    venv.set_attr("flag", ["a", "b"])
    assert venv.get_attr("flag") == ("a", "b")
    pids = venv.pool.worker_pids
    with pytest.raises(KeyError, match="no such thing"):
        venv.call("broken")
    assert venv.pool.worker_pids == pids  # a raising method does not cost the env
    assert venv.failures == []


# -- failures ------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("fault", "kind", "type_name", "tail"),
    [
        ("raise", "error", "ValueError", "solver diverged"),
        ("unpicklable", "error", "Unpicklable", "exception with a lock"),
        ("kill", "crash", "WorkerCrashed", "worker pid"),
        ("exit", "crash", "WorkerCrashed", "about to exit hard"),
        ("hang", "timeout", "Timeout", "worker pid"),
        ("bad-reply", "error", "TypeError", ""),
    ],
)
def test_a_failing_env_is_truncated_respawned_and_the_others_keep_stepping(
    make_vec, tmp_path, fault, kind, type_name, tail
):
    venv = make_vec(fns(3, tmp_path, {1: fault}), step_timeout=2)
    venv.reset(seed=3)
    old_pid = venv.pool.worker_pids[1]
    obs, rewards, terms, truncs, infos = venv.step(np.zeros((3, 1), np.float32))
    assert list(obs[:, 1]) == [1, 1, 1]
    started = time.monotonic()
    obs, rewards, terms, truncs, infos = venv.step(np.zeros((3, 1), np.float32))
    assert time.monotonic() - started < 8  # reported within (a generous bound of) the timeout
    assert list(truncs) == [False, True, False] and not terms.any()
    assert rewards[1] == 0.0 and rewards[0] == rewards[2] == 1.0
    assert list(obs[:, 1]) == [2, 0, 2]  # env 1 is in a fresh episode, the others went on
    assert infos["_failure"].tolist() == [False, True, False]
    failure = {k: infos["failure"][k][1] for k in ("env_index", "kind", "type", "log_tail")}
    assert failure["env_index"] == 1 and failure["kind"] == kind
    assert failure["type"].endswith(type_name)
    assert tail in failure["log_tail"]
    assert infos["final_obs"][1][1] == 1  # the last observation the learner saw
    assert infos["final_info"]["failure"]["kind"][1] == kind
    assert not alive(old_pid)
    assert venv.pool.worker_pids[1] != old_pid
    # the respawned env steps normally from now on
    for t in range(1, EPISODE):
        obs, rewards, terms, truncs, infos = venv.step(np.zeros((3, 1), np.float32))
        assert obs[1, 1] == t
    assert len(venv.failures) == 1 and isinstance(venv.failures[0], EnvFailure)


@pytest.mark.parametrize("fault", ["reset-raise", "reset-hang"])
def test_failed_reset_is_retried_on_a_fresh_worker(make_vec, tmp_path, fault):
    venv = make_vec(fns(2, tmp_path, {0: fault}), reset_timeout=2)
    obs, infos = venv.reset(seed=5)
    assert list(obs[:, 1]) == [0, 0]
    assert infos["_reset_failures"].tolist() == [True, False]
    (failure,) = infos["reset_failures"][0]
    assert failure["phase"] == "reset" and failure["env_index"] == 0
    assert failure["kind"] == ("error" if fault == "reset-raise" else "timeout")
    # the retry used a seed derived from the env's own, not the same one again
    assert obs[0, 2] != gym.utils.seeding.np_random(5)[0].random()


def test_failed_reset_during_autoreset_keeps_the_completed_episode(make_vec, tmp_path):
    marker = tmp_path / "late-fault"
    env_fns = [
        functools.partial(ScriptedEnv, 0),
        functools.partial(ScriptedEnv, 1, "reset-raise", marker=str(marker)),
    ]
    venv = make_vec(env_fns)
    marker.touch()  # no fault at the first reset ...
    venv.reset(seed=0)
    marker.unlink()  # ... but at the automatic one
    for _ in range(EPISODE):
        obs, rewards, _terms, truncs, infos = venv.step(np.zeros((2, 1), np.float32))
    # the episode itself completed: real reward, no failure, a normal time-limit end
    assert list(rewards) == [1.0, 1.0] and truncs.all()
    assert "failure" not in infos
    assert infos["_reset_failures"].tolist() == [False, True]
    assert list(obs[:, 1]) == [0, 0]


def test_failure_budget_stops_the_run_with_a_report(tmp_path):
    started = time.monotonic()
    with pytest.raises(FailureBudgetExceededError) as caught:
        ResilientVectorEnv(
            fns(2, tmp_path, {1: "always-reset-raise"}),
            max_failures_per_env=3,
            failure_window=10,
            log_dir=tmp_path / "logs",
        ).reset(seed=0)
    assert time.monotonic() - started < 60
    error = caught.value
    assert list(error.failures) == [1] and len(error.failures[1]) == 3
    text = str(error)
    assert "env 1 failed 3 times" in text and "the case is broken" in text
    assert "env 1: 3 failure(s)" in text


def test_budget_is_a_sliding_window_of_episodes(make_vec, tmp_path):
    # one failure per episode, fired through fresh markers, never reaches 3 within 2 episodes
    venv = make_vec(fns(1, tmp_path, {0: "raise"}), max_failures_per_env=2, failure_window=2)
    marker = Path(tmp_path / "fault-0")
    venv.reset(seed=0)
    for _ in range(4):
        marker.unlink(missing_ok=True)
        for _ in range(EPISODE):
            truncs = venv.step(np.zeros((1, 1), np.float32))[3]
            if truncs[0]:
                break
        # let one episode complete cleanly between failures
        for _ in range(EPISODE + 1):
            _obs, _rewards, _terms, truncs, _infos = venv.step(np.zeros((1, 1), np.float32))
            if truncs[0]:
                break
    assert len(venv.failures) == 4


def test_fatal_error_stops_at_once_with_the_original_type(tmp_path):
    started = time.monotonic()
    with pytest.raises(ConfigError, match="bad key"):
        ResilientVectorEnv(
            fns(2, tmp_path, {0: "config-error"}), log_dir=tmp_path / "logs", reset_timeout=10
        )
    assert time.monotonic() - started < 30


def test_recorded_process_groups_are_killed_when_an_env_hangs(make_vec, tmp_path):
    run_dir = tmp_path / "env0"
    pidfile = tmp_path / "solver.pid"

    class SolverEnv(ScriptedEnv):
        """Starts a 'solver' in its own session and records its group, like the Adapter."""

        def reset(self, *, seed=None, options=None):
            proc = subprocess.Popen(
                [sys.executable, "-c", "import time; time.sleep(1000)"], start_new_session=True
            )
            PidRegistry(self.run_dir).add(proc.pid)
            Path(pidfile).write_text(str(proc.pid))
            return super().reset(seed=seed, options=options)

    env_fns = [
        functools.partial(SolverEnv, 0, "hang", marker=str(tmp_path / "m"), run_dir=str(run_dir))
    ]
    venv = make_vec(env_fns, step_timeout=1.5)
    venv.reset(seed=0)
    assert venv.pool.run_dirs == [str(run_dir)]
    solver = int(pidfile.read_text())
    assert alive(solver)
    venv.step(np.zeros((1, 1), np.float32))
    _obs, _rewards, _terms, truncs, infos = venv.step(np.zeros((1, 1), np.float32))
    assert truncs[0] and infos["failure"]["kind"][0] == "timeout"
    assert infos["failure"]["killed_groups"][0] == [solver]
    assert not alive(solver)
    new_solver = int(pidfile.read_text())
    venv.close()
    assert not alive(new_solver)
    assert PidRegistry(run_dir).pgids() == []


def test_close_kills_workers_that_do_not_answer(tmp_path):
    venv = ResilientVectorEnv(
        fns(2, tmp_path, {0: "hang"}, at=1), log_dir=tmp_path / "logs", close_timeout=0.5
    )
    venv.reset()
    pids = venv.pool.worker_pids
    venv.step_async(np.zeros((2, 1), np.float32))
    time.sleep(0.3)
    started = time.monotonic()
    venv.close()
    assert time.monotonic() - started < 10
    assert not any(alive(p) for p in pids)
    with pytest.raises(gym.error.ClosedEnvironmentError):
        venv.reset()


def test_workers_start_and_reset_concurrently(make_vec, tmp_path):
    started = time.monotonic()
    venv = make_vec(fns(4, tmp_path, build_sleep=1.0, reset_sleep=1.0))
    built = time.monotonic() - started
    venv.reset()
    reset = time.monotonic() - started - built
    # one after the other would take 4 s each; overlapping takes about 1 s
    assert built < 3.5 and reset < 3.0


def test_a_reply_that_stops_half_way_times_out_instead_of_blocking():
    from multiprocessing.connection import Pipe

    from gymprecice.vector.local import recv_bytes

    reader, writer = Pipe(duplex=True)
    big = os.urandom(3 * 1024 * 1024)
    threading.Thread(target=writer.send_bytes, args=(big,), daemon=True).start()
    assert recv_bytes(reader.fileno(), time.monotonic() + 30) == big
    for size in (1, 8, 16385):  # one write, header and body written apart
        writer.send_bytes(b"x" * size)
        assert recv_bytes(reader.fileno(), time.monotonic() + 30) == b"x" * size
    os.write(writer.fileno(), (1000).to_bytes(4, "big") + b"only part of it")
    started = time.monotonic()
    with pytest.raises(TimeoutError):
        recv_bytes(reader.fileno(), time.monotonic() + 0.5)
    assert time.monotonic() - started < 5


def test_describe_exception_is_plain_data_even_for_unpicklable_errors():
    desc = describe_exception(Unpicklable("x"))
    assert desc["type"].endswith("Unpicklable") and desc["message"] == "x"
    assert desc["pickled"] is None
    assert cloudpickle.loads(cloudpickle.dumps(desc)) == desc


def test_start_method_fork_is_refused(tmp_path):
    with pytest.raises(ValueError, match="fork"):
        EnvPool(fns(1, tmp_path), start_method="fork", log_dir=tmp_path / "logs")


def test_spawn_start_method_works(make_vec, tmp_path):
    venv = make_vec(fns(2, tmp_path, {1: "kill"}), start_method="spawn")
    venv.reset(seed=0)
    venv.step(np.zeros((2, 1), np.float32))
    _obs, _rewards, _terms, truncs, _infos = venv.step(np.zeros((2, 1), np.float32))
    assert list(truncs) == [False, True]


def test_killed_learner_leaves_no_worker_behind(tmp_path):
    script = tmp_path / "learner.py"
    script.write_text(
        "import functools, sys, time, cloudpickle\n"
        "import gymnasium as gym, numpy as np\n"
        "from gymprecice.vector import ResilientVectorEnv\n"
        "class E(gym.Env):\n"
        "    observation_space = gym.spaces.Box(0, 1, (1,))\n"
        "    action_space = gym.spaces.Box(0, 1, (1,))\n"
        "    def reset(self, *, seed=None, options=None):\n"
        "        return np.zeros(1, np.float32), {}\n"
        "if __name__ == '__main__':\n"
        f"    v = ResilientVectorEnv([E, E], log_dir={str(tmp_path / 'logs')!r})\n"
        "    print(*v.pool.worker_pids, flush=True)\n"
        "    time.sleep(1000)\n"
    )
    learner = subprocess.Popen(
        [sys.executable, str(script)], stdout=subprocess.PIPE, text=True, cwd=tmp_path
    )
    try:
        pids = [int(p) for p in learner.stdout.readline().split()]
        assert len(pids) == 2 and all(alive(p) for p in pids)
        learner.kill()
        learner.wait()
        deadline = time.monotonic() + 15
        while any(alive(p) for p in pids) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not any(alive(p) for p in pids)
    finally:
        learner.kill()


# -- telemetry -----------------------------------------------------------------------------


def test_telemetry_collects_per_step_timings_and_failures(make_vec, tmp_path):
    venv = make_vec(fns(2, tmp_path, {0: "raise"}, step_sleep=0.01))
    venv.reset(seed=0)
    for _ in range(6):
        venv.step(np.zeros((2, 1), np.float32))
        time.sleep(0.005)
    telemetry = venv.telemetry
    assert telemetry.steps == 11  # env 0 lost one step to the failure
    env_step = telemetry.stats("env_step_s")
    assert env_step is not None and env_step.mean >= 0.01
    learner = telemetry.stats("learner_s")
    assert learner is not None and learner.count == 5 and learner.mean >= 0.005
    drained = telemetry.drain()
    assert drained["failures"] == 1.0 and drained["env_step_s_count"] == 11
    assert telemetry.drain()["failures"] == 0.0
    text = telemetry.summary()
    assert "env 0: 1 (ValueError x1)" in text and "vector env overhead" in text


@pytest.mark.parametrize("as_timing", [False, True], ids=["dict", "Timing"])
def test_telemetry_prefers_the_adapter_timing(as_timing):
    from gymprecice.env.core import Timing

    telemetry = Telemetry(num_envs=1)
    seconds = {"wait_s": 0.5, "env_s": 0.1, "precice_s": 0.45}
    info = {"timing": Timing(seconds) if as_timing else seconds}  # Timing: what Adapter gives
    telemetry.record_step(info, worker_s=0.7, roundtrip_s=0.71)
    telemetry.record_reset({"timing": {"reset_s": 3.0}}, worker_s=3.2)
    assert telemetry.stats("solver_wait_s").mean == 0.5
    assert telemetry.stats("env_s").mean == 0.1
    assert telemetry.stats("reset_s").mean == 3.0
    assert telemetry.stats("vector_overhead_s").mean == pytest.approx(0.01)
    assert telemetry.drain()["solver_fraction"] == pytest.approx(0.5 / 0.71)


# -- Stable-Baselines3 facade ---------------------------------------------------------------

sb3 = pytest.importorskip("stable_baselines3")


def test_sb3_facade_follows_subprocvecenv_conventions(make_vec, tmp_path):
    from stable_baselines3.common.monitor import Monitor

    from gymprecice.learners.sb3 import ResilientSubprocVecEnv

    venv = make_vec(fns(2, tmp_path, {1: "raise"}), cls=ResilientSubprocVecEnv)
    venv.seed(11)
    venv.set_options({"split": "eval"})
    obs = venv.reset()
    assert obs.shape == (2, 3)
    assert np.allclose(obs[:, 2], [gym.utils.seeding.np_random(11 + i)[0].random() for i in (0, 1)])
    assert [i["options"] for i in venv.reset_infos] == [{"split": "eval"}] * 2
    venv.step_async(np.zeros((2, 1), np.float32))
    obs, _, dones, infos = venv.step_wait()
    assert not dones.any() and infos[0]["TimeLimit.truncated"] is False
    obs, _, dones, infos = venv.step(np.zeros((2, 1), np.float32))
    assert list(dones) == [False, True]
    assert infos[1]["failure"]["type"] == "ValueError"
    assert infos[1]["TimeLimit.truncated"] is True
    assert infos[1]["terminal_observation"][1] == 1
    assert venv.reset_infos[1]["options"] == {"split": "eval"}
    for _ in range(2):
        obs, _rews, dones, infos = venv.step(np.zeros((2, 1), np.float32))
    assert list(dones) == [True, False]
    assert infos[0]["terminal_observation"][1] == EPISODE and infos[0]["TimeLimit.truncated"]
    assert obs[0, 1] == 0
    assert venv.env_method("whoami", "?", indices=[1]) == ["env-1?"]
    assert venv.get_attr("index") == [0, 1]
    venv.set_attr("flag", "x", indices=0)
    assert venv.get_attr("flag") == ["x", "unset"]
    assert venv.env_is_wrapped(Monitor) == [False, False]
    assert venv.has_attr("whoami") and not venv.has_attr("nope")
    # answering SB3's questions must not load SB3 (and PyTorch) into every env worker
    assert venv.env_method("imported", "torch") == [False, False]


def test_a_worker_dying_in_a_call_is_respawned_and_its_episode_ends_at_the_next_step(
    make_vec, tmp_path
):
    from gymprecice.learners.sb3 import ResilientSubprocVecEnv

    venv = make_vec(fns(2, tmp_path), cls=ResilientSubprocVecEnv)
    venv.reset()
    venv.step(np.zeros((2, 1), np.float32))
    old = venv.pool.worker_pids[1]
    marker = str(tmp_path / "call-marker")
    assert venv.env_method("crash_once", marker, indices=[1]) == ["env-1 alive"]
    assert venv.pool.worker_pids[1] != old and not alive(old)
    obs, _, dones, infos = venv.step(np.zeros((2, 1), np.float32))
    assert list(dones) == [False, True]
    assert infos[1]["failure"]["phase"] == "call" and infos[1]["failure"]["kind"] == "crash"
    assert infos[1]["terminal_observation"][1] == 1 and obs[1, 1] == 0
    assert obs[0, 1] == 2


def test_sb3_env_is_wrapped_matches_wrappers_and_their_bases(make_vec, tmp_path):
    from gymprecice.learners.sb3 import ResilientSubprocVecEnv

    venv = make_vec([functools.partial(time_limited, 0)], cls=ResilientSubprocVecEnv)
    assert venv.env_is_wrapped(gym.wrappers.TimeLimit) == [True]
    assert venv.env_is_wrapped(gym.Wrapper) == [True]
    assert venv.env_is_wrapped(gym.wrappers.ClipAction) == [False]


def test_sb3_ppo_trains_through_failures_and_logs_telemetry(tmp_path, capsys):
    from stable_baselines3 import PPO
    from stable_baselines3.common.logger import configure

    from gymprecice.learners.sb3 import ResilientSubprocVecEnv, TelemetryCallback

    venv = ResilientSubprocVecEnv(
        fns(2, tmp_path, {0: "kill", 1: "raise"}, at=3),
        log_dir=tmp_path / "logs",
        step_timeout=10,
    )
    try:
        model = PPO("MlpPolicy", venv, n_steps=16, batch_size=16, n_epochs=1, seed=0)
        model.set_logger(configure(str(tmp_path / "tb"), ["csv"]))
        model.learn(total_timesteps=64, callback=TelemetryCallback(print_summary=True))
    finally:
        venv.close()
    assert len(venv.failures) == 2
    header = (tmp_path / "tb" / "progress.csv").read_text().splitlines()[0].split(",")
    assert "gymprecice/env_step_s_mean" in header and "gymprecice/failures_total" in header
    assert "gymprecice vector env: 2 envs" in capsys.readouterr().out


def test_telemetry_summary_table_is_aligned():
    from gymprecice.vector.telemetry import SERIES

    telemetry = Telemetry(num_envs=1)
    for name in SERIES:
        telemetry.add(name, 0.125)
    lines = telemetry.summary().splitlines()
    table = [ln for ln in lines if ln.startswith("  ") and ln.rstrip().endswith("0.125")]
    header = next(ln for ln in lines if "[seconds]" in ln)
    assert len(table) == len(SERIES)
    # every row's last column ends where the header's "max" ends
    assert {len(row.rstrip()) for row in table} == {len(header.rstrip())}
