"""The pool's contract, whoever hosts the envs: deadlines, failure budget, respawn, telemetry.

:class:`EnvPool` drives N envs through a backend (:mod:`gymprecice.vector.local`: worker
processes on this machine; :mod:`gymprecice.vector.ray`: Ray actors on a cluster). The
backend only starts a host, carries requests, waits for replies, kills a host and cleans
up what its env started. Everything else is decided here, the same for every backend:

* the learner waits on all envs at once with a deadline per env: ``step_timeout`` for a
  step, ``reset_timeout`` for a reset or the construction of an env;
* an env that raised (*error*), whose host died (*crash*) or that did not answer in time
  (*timeout*) is killed with every process group it recorded in
  ``<run_dir>/.gymprecice/pids`` (on the machine where it ran), the failure is logged
  with the env index and the log tail, and the env is started again and reset. Its
  partial episode ends as **truncated** with the failure in ``info["failure"]`` (and a
  line of ``<log_dir>/failures.jsonl``); the other envs' results are untouched;
* a failure budget (``max_failures_per_env`` within the last ``failure_window``
  episodes of an env) stops the run with :class:`FailureBudgetExceededError` instead of
  respawning a broken env forever; ``fatal_errors`` stop it at once;
* hosts start concurrently and resets run concurrently without any global lock.

A step is a generator per env (a *job*): it sends a request, yields the deadline of the
answer, and gets back a :class:`~gymprecice.vector.contract.Reply` (the message, a crash or
a timeout). What a backend offers and returns is :mod:`gymprecice.vector.contract`, which
the pool and the backends read; the pool imports a backend only when it makes one.
"""

from __future__ import annotations

import atexit
import contextlib
import json
import logging
import math
import os
import time
import weakref
from collections import deque
from collections.abc import Callable, Generator, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cloudpickle
import gymnasium as gym
import numpy as np

from gymprecice.env.processes import describe_returncode
from gymprecice.vector.contract import TIMEOUT, Backend, Host, Reply
from gymprecice.vector.failures import (
    DEFAULT_FATAL_ERRORS,
    TAIL_LINES,
    EnvFailedError,
    EnvFailure,
    FailureBudgetExceededError,
    unpickle_exception,
)
from gymprecice.vector.telemetry import Telemetry

log = logging.getLogger("gymprecice.vector")

DEFAULT_STEP_TIMEOUT = 900.0
DEFAULT_RESET_TIMEOUT = 1800.0
DEFAULT_CALL_TIMEOUT = 120.0
DEFAULT_CLOSE_TIMEOUT = 30.0
#: every failure of a pool's envs, one JSON line each (``EnvFailure.to_info``), in its
#: ``log_dir``: what a run's restarts were, after it ended (appended to across runs)
FAILURES_FILE = "failures.jsonl"


@dataclass
class StepResult:
    """One env's part of a batch step, same-step autoreset applied.

    When the episode ended (``terminated or truncated``), ``obs``/``info`` belong to the
    next episode's reset and ``final_obs``/``final_info`` to the ended one. ``failure`` is
    set when the episode was cut short by an env failure (then ``truncated`` is true,
    ``reward`` is 0 and ``final_obs`` is the last observation the learner received).
    """

    obs: Any
    reward: float
    terminated: bool
    truncated: bool
    info: dict[str, Any]
    final_obs: Any = None
    final_info: dict[str, Any] | None = None
    failure: EnvFailure | None = None

    @property
    def done(self) -> bool:
        return self.terminated or self.truncated


@dataclass
class _Outcome:
    value: Any = None
    failure: EnvFailure | None = None
    #: an exception raised by a called method (the env itself is fine)
    call_error: dict[str, Any] | None = None
    roundtrip: float = 0.0


@dataclass
class _Slot:
    """Everything the learner knows about env ``index`` across its workers' lives."""

    index: int
    failure_window: int
    worker: Host | None = None
    run_dir: str | None = None
    last_obs: Any = None
    episode_active: bool = False
    pending_failure: EnvFailure | None = None
    seed: int | None = None
    options: dict[str, Any] | None = None
    episodes: int = 0
    spawns: int = 0
    failures: list[EnvFailure] = field(default_factory=list)
    history: deque[bool] = field(init=False)

    def __post_init__(self) -> None:
        self.history = deque(maxlen=self.failure_window)


_Job = Generator[float, Reply, Any]


@dataclass
class _Batch:
    jobs: dict[int, _Job]
    waiting: dict[int, float] = field(default_factory=dict)
    results: dict[int, Any] = field(default_factory=dict)


_LIVE_POOLS: weakref.WeakSet[EnvPool] = weakref.WeakSet()


@atexit.register
def _close_live_pools() -> None:
    for pool in list(_LIVE_POOLS):
        with contextlib.suppress(Exception):
            pool.close(timeout=2.0)


class EnvPool:
    """N env workers behind deadlines, respawning failed envs (see the module docstring).

    One pool is driven by one thread (the learner's). As with any ``forkserver`` or
    ``spawn`` pool, a script that builds one must guard its entry point with
    ``if __name__ == "__main__":``. With ``spawn``, a worker's parent is the thread that
    started it; if that thread ends, the worker gets SIGTERM (and cleans up).

    Parameters
    ----------
    env_fns:
        One picklable callable per env that builds it (pickled with cloudpickle, so
        lambdas and ``functools.partial`` work). It must build the *same* env every time it
        is called: a failed env is rebuilt from it.
    step_timeout, reset_timeout:
        Seconds an env may take for one step / one reset (or to be built); ``None`` for
        no limit. These are the outer safety net: keep them above the Adapter's own
        ``timeouts`` (``progress``, ``reset``) so that its precise reports come first.
    call_timeout:
        Seconds for ``call``/``get_attr``/``set_attr``.
    close_timeout:
        Seconds :meth:`close` waits for the envs' own ``close()`` before killing them.
    max_failures_per_env, failure_window:
        Stop with :class:`FailureBudgetExceededError` when an env failed
        ``max_failures_per_env`` times within its last ``failure_window`` episodes.
    fatal_errors:
        Exception types that stop the run at the first occurrence (the original exception
        is re-raised when it can be rebuilt, else :class:`EnvFailedError`).
    start_method:
        ``"forkserver"`` (default where available) or ``"spawn"``. ``fork`` is refused: a
        forked copy of a learner with threads (PyTorch) can deadlock. Local backend only.
    log_dir:
        Where each worker writes ``env_<i>.log`` (default ``gymprecice-runs/workers`` in
        the working directory, beside the Adapter's default run root).
    kill_grace:
        Seconds between SIGTERM and SIGKILL for the env's recorded process groups.
    daemon:
        Whether workers are daemonic (multiprocessing then also stops them at exit; a
        daemonic worker cannot start multiprocessing children of its own, ``subprocess``
        is fine). Local backend only.
    telemetry:
        Where timings and failures are recorded (default: a new
        :class:`~gymprecice.telemetry.Telemetry`).
    backend:
        Where the envs live: ``None`` or ``"local"`` for worker processes on this machine
        (:class:`~gymprecice.vector.local.LocalBackend`), ``"ray"`` for Ray actors
        (:class:`~gymprecice.vector.ray.RayBackend`, needs ``gymprecice-core[ray]``), or
        a backend object.
    """

    def __init__(
        self,
        env_fns: Sequence[Callable[[], gym.Env]],
        *,
        step_timeout: float | None = DEFAULT_STEP_TIMEOUT,
        reset_timeout: float | None = DEFAULT_RESET_TIMEOUT,
        call_timeout: float | None = DEFAULT_CALL_TIMEOUT,
        close_timeout: float = DEFAULT_CLOSE_TIMEOUT,
        max_failures_per_env: int = 5,
        failure_window: int = 20,
        fatal_errors: Iterable[type[BaseException]] = DEFAULT_FATAL_ERRORS,
        start_method: str | None = None,
        daemon: bool = True,
        log_dir: str | os.PathLike[str] | None = None,
        kill_grace: float = 1.0,
        telemetry: Telemetry | None = None,
        backend: Backend | str | None = None,
    ) -> None:
        env_fns = list(env_fns)
        if not env_fns:
            raise ValueError("EnvPool needs at least one env_fn")
        if max_failures_per_env < 1 or failure_window < 1:
            raise ValueError("max_failures_per_env and failure_window must be at least 1")
        for name, value in (
            ("step_timeout", step_timeout),
            ("reset_timeout", reset_timeout),
            ("call_timeout", call_timeout),
        ):
            if value is not None and value <= 0:
                raise ValueError(f"{name} must be a positive number of seconds or None")
        self.backend = _make_backend(backend, start_method, daemon)
        self.start_method = getattr(self.backend, "start_method", None)
        self.num_envs = len(env_fns)
        self.step_timeout = step_timeout
        self.reset_timeout = reset_timeout
        self.call_timeout = call_timeout
        self.close_timeout = close_timeout
        self.max_failures_per_env = max_failures_per_env
        self.failure_window = failure_window
        self.kill_grace = kill_grace
        self.daemon = daemon
        self.log_dir = Path(log_dir if log_dir is not None else Path("gymprecice-runs", "workers"))
        self.log_dir = self.log_dir.resolve()
        self.log_dir.mkdir(parents=True, exist_ok=True)
        fatal = tuple(fatal_errors)
        self._payloads: list[bytes] = []
        for index, fn in enumerate(env_fns):
            try:
                self._payloads.append(cloudpickle.dumps((fn, fatal)))
            except Exception as exc:
                raise TypeError(
                    f"env_fns[{index}] cannot be pickled to reach its worker process ({exc}); "
                    "use a module-level function, a class, or functools.partial of one"
                ) from exc
        self._slots = [_Slot(i, failure_window) for i in range(self.num_envs)]
        self.telemetry = telemetry or Telemetry(self.num_envs)
        self.telemetry.num_envs = self.num_envs
        self._closed = False
        self._pending: _Batch | None = None
        self._reset_done = False
        self._last_step_end: float | None = None
        self._step_sent: float | None = None
        _LIVE_POOLS.add(self)

        ready = self._run({slot.index: self._start_job(slot) for slot in self._slots})
        first = ready[0]
        self.observation_space: gym.Space = first["observation_space"]
        self.action_space: gym.Space = first["action_space"]
        self.metadata: dict[str, Any] = first["metadata"]
        self.render_mode: str | None = first["render_mode"]
        self.spec = first["spec"]
        for index in range(1, self.num_envs):
            info = ready[index]
            if info["observation_space"] != self.observation_space:
                self.close()
                raise RuntimeError(
                    f"env {index} has observation space {info['observation_space']}, env 0 has "
                    f"{self.observation_space}; all envs of a vector env must agree"
                )
            if info["action_space"] != self.action_space:
                self.close()
                raise RuntimeError(
                    f"env {index} has action space {info['action_space']}, env 0 has "
                    f"{self.action_space}; all envs of a vector env must agree"
                )

    # -- public API ------------------------------------------------------------------------
    @property
    def closed(self) -> bool:
        return self._closed

    @property
    def failures(self) -> list[EnvFailure]:
        """Every failure of the run, in order."""
        return sorted((f for s in self._slots for f in s.failures), key=lambda f: f.wall_time)

    def failures_of(self, index: int) -> list[EnvFailure]:
        return list(self._slots[index].failures)

    @property
    def run_dirs(self) -> list[str | None]:
        """Each env's run directory (where its pid registry is), when it has one."""
        return [slot.run_dir for slot in self._slots]

    @property
    def hosts(self) -> list[Host | None]:
        """Each env's current host (worker process, actor), None while it has none."""
        return [slot.worker for slot in self._slots]

    @property
    def worker_pids(self) -> list[int | None]:
        return [slot.worker.pid if slot.worker else None for slot in self._slots]

    @property
    def log_files(self) -> list[Path]:
        return [self.log_dir / f"env_{slot.index}.log" for slot in self._slots]

    def reset(
        self,
        seeds: Sequence[int | None] | None = None,
        options: Sequence[Mapping[str, Any] | None] | None = None,
        indices: Sequence[int] | None = None,
    ) -> dict[int, tuple[Any, dict[str, Any]]]:
        """Reset the envs in ``indices`` (default all) concurrently; ``{index: (obs, info)}``.

        ``seeds[i]``/``options[i]`` are per env (of all ``num_envs``). An env whose reset
        fails is respawned and reset again (with a seed derived from its own) until it
        works or its failure budget is spent; the failures are in
        ``info["reset_failures"]``.
        """
        self._check_idle()
        targets = list(range(self.num_envs)) if indices is None else list(indices)
        seeds = list(seeds) if seeds is not None else [None] * self.num_envs
        options = list(options) if options is not None else [None] * self.num_envs
        jobs = {
            i: self._reset_job(
                self._slots[i], seeds[i], dict(options[i]) if options[i] is not None else None
            )
            for i in targets
        }
        results = self._run(jobs)
        self._reset_done = True
        self._last_step_end = None
        return results

    def step_async(self, actions: Sequence[Any]) -> None:
        """Send one action to every env (returns at once)."""
        self._check_idle()
        if not self._reset_done:
            raise gym.error.ResetNeeded("call reset() before stepping the vector env")
        if len(actions) != self.num_envs:
            raise ValueError(f"expected {self.num_envs} actions, got {len(actions)}")
        now = time.perf_counter()
        if self._last_step_end is not None:
            self.telemetry.add("learner_s", now - self._last_step_end)
        self._step_sent = now
        jobs = {slot.index: self._step_job(slot, actions[slot.index]) for slot in self._slots}
        self._pending = self._start(jobs)

    def step_wait(self) -> list[StepResult]:
        """Wait for the step sent by :meth:`step_async`; one :class:`StepResult` per env."""
        if self._closed:
            raise gym.error.ClosedEnvironmentError("the vector env is closed")
        if self._pending is None:
            raise gym.error.NoAsyncCallError("step_wait() without step_async()", "step")
        batch, self._pending = self._pending, None
        results = self._finish(batch)
        self._last_step_end = time.perf_counter()
        if self._step_sent is not None:
            self.telemetry.add("batch_step_s", self._last_step_end - self._step_sent)
        return [results[i] for i in range(self.num_envs)]

    def step(self, actions: Sequence[Any]) -> list[StepResult]:
        self.step_async(actions)
        return self.step_wait()

    def call(self, command: str, data: Any, indices: Sequence[int] | None = None) -> list[Any]:
        """Run a worker command (``call``, ``method``, ``get``, ``set``, ``apply``, ``has``,
        ``wrapped``) on the envs in ``indices`` (default all); one result per env.

        An exception raised by the env's method is re-raised here (rebuilt when possible)
        and the env is left as it is. A worker that dies or hangs during a call is
        respawned and the call retried once; its episode then ends with a failure at the
        next step.
        """
        self._check_idle()
        targets = list(range(self.num_envs)) if indices is None else list(indices)
        results = self._run({i: self._call_job(self._slots[i], command, data) for i in targets})
        values = []
        for i in targets:
            value = results[i]
            if isinstance(value, _CallFailed):
                raise value.exception()
            values.append(value)
        return values

    def close(self, timeout: float | None = None) -> None:
        """Close every env (``env.close()`` in its worker), then kill what is left.

        Waits up to ``timeout`` (default ``close_timeout``) seconds for the workers to
        exit on their own, then SIGKILLs each worker's process group and every process
        group its env recorded. Idempotent.
        """
        if self._closed:
            return
        self._closed = True
        _LIVE_POOLS.discard(self)
        if self._pending is not None:
            for job in self._pending.jobs.values():
                job.close()
            self._pending = None
        live = [slot.worker for slot in self._slots if slot.worker is not None]
        limit = self.close_timeout if timeout is None else timeout
        with contextlib.suppress(Exception):
            self.backend.close(live, limit)
        for slot in self._slots:
            worker, slot.worker = slot.worker, None
            if worker is not None:
                with contextlib.suppress(Exception):
                    worker.kill()
            try:
                self.backend.cleanup(slot.run_dir, worker, self.kill_grace)
            except Exception as exc:
                log.debug("env %d: could not read its pid registry: %s", slot.index, exc)
        with contextlib.suppress(Exception):
            self.backend.shutdown()

    def __del__(self) -> None:
        with contextlib.suppress(Exception):
            if not self._closed:
                self.close(timeout=1.0)

    # -- jobs: one generator per env and operation -------------------------------------------
    # A job sends a request to its env's worker, then yields the deadline of the answer;
    # the driver (_finish) sends it back a Reply: the message, a crash or a timeout.

    def _start_job(self, slot: _Slot) -> _Job:
        while True:
            outcome = yield from self._spawn(slot)
            if outcome.failure is None:
                return outcome.value

    def _reset_job(self, slot: _Slot, seed: int | None, options: dict[str, Any] | None) -> _Job:
        if slot.episode_active:
            slot.history.append(False)  # the episode ended, just not by itself
        slot.episode_active = False
        slot.pending_failure = None
        slot.seed = seed
        slot.options = options
        obs, info = yield from self._episode_start(slot, seed, options)
        return obs, info

    def _step_job(self, slot: _Slot, action: Any) -> _Job:
        failure, slot.pending_failure = slot.pending_failure, None
        if failure is None and slot.worker is None and slot.failures:
            failure = slot.failures[-1]  # a call killed it and could not restart it
        if failure is None:
            outcome = yield from self._request(slot, "step", "step", action, self.step_timeout)
            if outcome.failure is None:
                (obs, reward, terminated, truncated, info), worker_s = outcome.value
                self.telemetry.record_step(info, worker_s, outcome.roundtrip)
                terminated, truncated = bool(terminated), bool(truncated)
                if not (terminated or truncated):
                    slot.last_obs = obs
                    return StepResult(obs, float(reward), False, False, dict(info))
                slot.history.append(False)
                slot.episode_active = False
                new_obs, new_info = yield from self._episode_start(slot, None, slot.options)
                return StepResult(
                    new_obs,
                    float(reward),
                    terminated,
                    truncated,
                    new_info,
                    final_obs=obs,
                    final_info=dict(info),
                )
            failure = outcome.failure
        final_obs = slot.last_obs
        new_obs, new_info = yield from self._episode_start(
            slot, self._derived_seed(slot), slot.options
        )
        new_info = {**new_info, "failure": failure.to_info()}
        return StepResult(
            new_obs,
            0.0,
            False,
            True,
            new_info,
            final_obs=final_obs,
            final_info={"failure": failure.to_info()},
            failure=failure,
        )

    def _call_job(self, slot: _Slot, command: str, data: Any) -> _Job:
        last: EnvFailure | None = None
        was_active = slot.episode_active
        for _ in range(2):
            if slot.worker is None:
                started = yield from self._spawn(slot)
                if started.failure is not None:
                    last = started.failure
                    continue
            outcome = yield from self._request(slot, "call", command, data, self.call_timeout)
            if outcome.call_error is not None:
                return _CallFailed(slot.index, command, data, outcome.call_error)
            if outcome.failure is None:
                return outcome.value[0]
            last = outcome.failure
            if was_active:
                # The episode died with the worker: the next step reports it (truncated).
                slot.pending_failure = last
        assert last is not None
        return _CallFailed(slot.index, command, data, None, last)

    def _episode_start(
        self, slot: _Slot, seed: int | None, options: dict[str, Any] | None
    ) -> Generator[float, Reply, tuple[Any, dict[str, Any]]]:
        """Reset the env (respawning it first if needed) until it works or the budget ends."""
        failures: list[EnvFailure] = []
        while True:
            if slot.worker is None:
                started = yield from self._spawn(slot)
                if started.failure is not None:
                    failures.append(started.failure)
                    seed = self._derived_seed(slot)
                    continue
            outcome = yield from self._request(
                slot, "reset", "reset", {"seed": seed, "options": options}, self.reset_timeout
            )
            if outcome.failure is not None:
                failures.append(outcome.failure)
                seed = self._derived_seed(slot)
                continue
            (obs, info), worker_s = outcome.value
            info = dict(info)
            self.telemetry.record_reset(info, worker_s)
            slot.last_obs = obs
            slot.episode_active = True
            slot.episodes += 1
            if failures:
                info["reset_failures"] = [f.to_info() for f in failures]
            return obs, info

    def _spawn(self, slot: _Slot) -> Generator[float, Reply, _Outcome]:
        """Start a worker for ``slot`` and wait until its env is built."""
        started = time.perf_counter()
        log_path = self.log_dir / f"env_{slot.index}.log"
        slot.worker = self.backend.spawn(slot.index, self._payloads[slot.index], log_path)
        if slot.spawns:
            self.telemetry.respawns += 1
        slot.spawns += 1
        outcome = yield from self._await(slot, "start", self.reset_timeout)
        if outcome.failure is None:
            ready, _ = outcome.value
            slot.run_dir = ready.get("run_dir") or slot.run_dir
            self.telemetry.add("spawn_s", time.perf_counter() - started)
            outcome.value = ready
        return outcome

    def _request(
        self, slot: _Slot, phase: str, command: str, data: Any, timeout: float | None
    ) -> Generator[float, Reply, _Outcome]:
        assert slot.worker is not None
        slot.worker.send(command, data)
        return (yield from self._await(slot, phase, timeout))

    def _await(
        self, slot: _Slot, phase: str, timeout: float | None
    ) -> Generator[float, Reply, _Outcome]:
        sent = time.perf_counter()
        deadline = math.inf if timeout is None else time.monotonic() + timeout
        reply = yield deadline
        roundtrip = time.perf_counter() - sent
        description: dict[str, Any] | None = None
        if reply.kind == "message":
            tag, value = reply.value
            if tag == "ok":
                return _Outcome(value=value, roundtrip=roundtrip)
            description = value
            if phase == "call" and not description.get("fatal"):
                return _Outcome(call_error=description, roundtrip=roundtrip)
            kind = "error"
        else:
            kind = reply.kind
        failure = self._fail(slot, kind, phase, description, timeout)
        return _Outcome(failure=failure, roundtrip=roundtrip)

    # -- failures ---------------------------------------------------------------------------
    def _fail(
        self,
        slot: _Slot,
        kind: str,
        phase: str,
        description: dict[str, Any] | None,
        timeout: float | None,
    ) -> EnvFailure:
        """Kill everything of the env, record and log the failure, enforce the budget."""
        worker, slot.worker = slot.worker, None
        returncode = None
        tail = ""
        log_file = None
        where = "host"
        if worker is not None:
            returncode = worker.kill()
            where = worker.where  # after the kill, which may learn that its node is lost
            tail = worker.tail()
            log_file = str(worker.log_path)
        killed: list[int] = []
        try:
            killed = self.backend.cleanup(slot.run_dir, worker, self.kill_grace)
        except OSError as exc:
            log.warning("env %d: could not read its pid registry: %s", slot.index, exc)
        desc = description or {}
        if kind == "crash":
            message = (
                f"env {slot.index}: its {where} died during '{phase}' "
                f"({describe_returncode(returncode) if returncode is not None else 'status unknown'})"
            )
            type_name = "WorkerCrashed"
        elif kind == "timeout":
            limit = f"{timeout:g} s" if timeout is not None else "its deadline"
            message = (
                f"env {slot.index}: no answer to '{phase}' within {limit}; the env looks "
                f"hung, so its {where} and {len(killed)} recorded process group(s) "
                "were killed"
            )
            type_name = "Timeout"
        else:
            message = desc.get("message", "")
            type_name = desc.get("type", "Exception")
        failure = EnvFailure(
            env_index=slot.index,
            kind=kind,
            phase=phase,
            type=type_name,
            message=message,
            log_tail=desc.get("log_tail") or tail,
            log_file=desc.get("log_file") if desc.get("log_tail") else log_file,
            returncode=desc.get("returncode", returncode),
            solver=desc.get("solver"),
            traceback=desc.get("traceback", ""),
            episode=slot.episodes,
            wall_time=time.time(),
            killed_groups=tuple(killed),
        )
        slot.failures.append(failure)
        slot.history.append(True)
        slot.episode_active = False
        self.telemetry.record_failure(failure)
        with contextlib.suppress(OSError), open(self.log_dir / FAILURES_FILE, "a") as record:
            record.write(json.dumps(failure.to_info(), default=str) + "\n")
        recent = sum(slot.history)
        log.warning(
            "env %d failed (%d of at most %d in its last %d episodes); restarting it. %s",
            slot.index,
            recent,
            self.max_failures_per_env,
            self.failure_window,
            failure.describe(tail_lines=TAIL_LINES),
        )
        if desc.get("fatal"):
            raise _FatalFailure(failure, desc)
        if recent >= self.max_failures_per_env:
            raise FailureBudgetExceededError(
                f"env {slot.index} failed {recent} times within its last "
                f"{len(slot.history)} episodes (max_failures_per_env="
                f"{self.max_failures_per_env}, failure_window={self.failure_window}); "
                "stopping the run instead of restarting it again. Fix the cause (see the log "
                "tails below) or raise the budget.",
                {s.index: s.failures for s in self._slots if s.failures},
            )
        return failure

    def _derived_seed(self, slot: _Slot) -> int | None:
        """Seed of a respawned env's first reset: reproducible from the env's own seed."""
        if slot.seed is None:
            return None
        state = np.random.SeedSequence([int(slot.seed) % 2**63, len(slot.failures)])
        return int(state.generate_state(1, dtype=np.uint32)[0])

    # -- the driver --------------------------------------------------------------------------
    def _check_idle(self) -> None:
        if self._closed:
            raise gym.error.ClosedEnvironmentError("the vector env is closed")
        if self._pending is not None:
            raise gym.error.AlreadyPendingCallError(
                "a step is in flight: call step_wait() first", "step"
            )

    def _run(self, jobs: dict[int, _Job]) -> dict[int, Any]:
        return self._finish(self._start(jobs))

    def _start(self, jobs: dict[int, _Job]) -> _Batch:
        batch = _Batch(jobs)
        try:
            for index in jobs:
                self._advance(batch, index, None)
        except BaseException as exc:
            self._abort(batch, exc)
            if isinstance(exc, _FatalFailure):
                raise exc.rebuild() from None
            raise
        return batch

    def _advance(self, batch: _Batch, index: int, reply: Reply | None) -> None:
        try:
            deadline = batch.jobs[index].send(reply)  # type: ignore[arg-type]
        except StopIteration as stop:
            batch.waiting.pop(index, None)
            batch.results[index] = stop.value
            return
        batch.waiting[index] = deadline

    def _finish(self, batch: _Batch) -> dict[int, Any]:
        try:
            while batch.waiting:
                earliest = min(batch.waiting.values())
                timeout = None if earliest == math.inf else max(0.0, earliest - time.monotonic())
                hosts = {i: self._slots[i].worker for i in batch.waiting}
                replies = self.backend.wait(hosts, timeout)  # type: ignore[arg-type]
                now = time.monotonic()
                for index in sorted(batch.waiting):
                    if index in replies:
                        reply = replies[index]
                    elif now >= batch.waiting[index]:
                        reply = TIMEOUT
                    else:
                        continue
                    self._advance(batch, index, reply)
        except BaseException as exc:
            self._abort(batch, exc)
            if isinstance(exc, _FatalFailure):
                raise exc.rebuild() from None
            raise
        return batch.results

    def _abort(self, batch: _Batch, exc: BaseException) -> None:
        """An exception escaped a job (budget spent, fatal error, Ctrl-C): close all."""
        for job in batch.jobs.values():
            with contextlib.suppress(Exception):
                job.close()
        if not isinstance(exc, (FailureBudgetExceededError, _FatalFailure)):
            log.warning("vector env interrupted by %s; closing it", type(exc).__name__)
        self.close(timeout=min(self.close_timeout, 5.0))


class _FatalFailure(Exception):
    """Internal: carries a fatal env failure out of the driver."""

    def __init__(self, failure: EnvFailure, description: dict[str, Any]):
        super().__init__(failure.message)
        self.failure = failure
        self.description = description

    def rebuild(self) -> BaseException:
        original = unpickle_exception(self.description.get("pickled"))
        text = (
            f"env {self.failure.env_index} failed with an error that restarting cannot fix, so "
            f"the run stops: {self.failure.type}: {self.failure.message}"
        )
        if original is not None:
            with contextlib.suppress(Exception):
                original.add_note(f"(raised in env {self.failure.env_index}'s worker process)")
            return original
        return EnvFailedError(text, self.failure)


@dataclass
class _CallFailed:
    index: int
    command: str
    data: Any
    description: dict[str, Any] | None
    failure: EnvFailure | None = None

    def exception(self) -> BaseException:
        what = self.data[0] if isinstance(self.data, tuple) and self.data else self.data
        if self.description is not None:
            original = unpickle_exception(self.description.get("pickled"))
            if original is not None:
                with contextlib.suppress(Exception):
                    original.add_note(f"(raised by {self.command} {what!r} in env {self.index})")
                return original
            return EnvFailedError(
                f"env {self.index}: {self.command} {what!r} raised "
                f"{self.description.get('type')}: {self.description.get('message')}"
            )
        assert self.failure is not None
        return EnvFailedError(
            f"env {self.index}: {self.command} {what!r} failed twice: {self.failure.message}",
            self.failure,
        )


def _make_backend(backend: Backend | str | None, start_method: str | None, daemon: bool) -> Backend:
    """The backend object for ``backend`` (a name, or an object used as it is)."""
    if backend is None or backend == "local":
        from gymprecice.vector.local import LocalBackend

        return LocalBackend(start_method, daemon)
    if start_method is not None:
        raise ValueError("start_method applies to the local backend only")
    if backend == "ray":
        from gymprecice.vector.ray import RayBackend

        return RayBackend()
    if isinstance(backend, str):
        raise ValueError(f"unknown backend {backend!r}: use 'local', 'ray' or a backend object")
    return backend
