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

The pool is split by what it does: this module is its face (construction, the public
API, closing); :mod:`.jobs` holds what each operation does with its answers,
:mod:`.restarts` the failure handling and restart policy (``failures.jsonl``, the
budget, fatal errors), :mod:`.driver` the loop that runs a batch of jobs against their
deadlines and :mod:`.slots` the per-env and per-batch records they share.
"""

from __future__ import annotations

import atexit
import contextlib
import logging
import os
import time
import weakref
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import cloudpickle
import gymnasium as gym

from gymprecice.vector.contract import Backend, Host
from gymprecice.vector.driver import BatchDriver
from gymprecice.vector.failures import DEFAULT_FATAL_ERRORS, EnvFailure
from gymprecice.vector.jobs import EnvJobs
from gymprecice.vector.restarts import FAILURES_FILE, CallFailed
from gymprecice.vector.slots import Batch, Slot, StepResult
from gymprecice.vector.telemetry import Telemetry

__all__ = [
    "DEFAULT_CALL_TIMEOUT",
    "DEFAULT_CLOSE_TIMEOUT",
    "DEFAULT_RESET_TIMEOUT",
    "DEFAULT_STEP_TIMEOUT",
    "FAILURES_FILE",
    "EnvPool",
    "StepResult",
]

log = logging.getLogger("gymprecice.vector")

DEFAULT_STEP_TIMEOUT = 900.0
DEFAULT_RESET_TIMEOUT = 1800.0
DEFAULT_CALL_TIMEOUT = 120.0
DEFAULT_CLOSE_TIMEOUT = 30.0


_LIVE_POOLS: weakref.WeakSet[EnvPool] = weakref.WeakSet()


@atexit.register
def _close_live_pools() -> None:
    for pool in list(_LIVE_POOLS):
        with contextlib.suppress(Exception):
            pool.close(timeout=2.0)


class EnvPool(EnvJobs, BatchDriver):
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
        self._slots = [Slot(i, failure_window) for i in range(self.num_envs)]
        self.telemetry = telemetry or Telemetry(self.num_envs)
        self.telemetry.num_envs = self.num_envs
        self._closed = False
        self._pending: Batch | None = None
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
            if isinstance(value, CallFailed):
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
