"""Fault-tolerant parallel environments: a process pool that never hangs and never loses work.

Training on 8-60 CFD environments for days breaks with ordinary vector envs: a hung solver
blocks the learner forever (their pipes wait without a timeout), an exception that cannot
be pickled turns into an ``EOFError`` for every env, and one env dying takes the whole run
with it. :class:`EnvPool` is the safety net around the Adapter's own watchdog:

* every env lives in its own worker process (``forkserver`` by default, ``spawn``
  allowed), in its own process group, and is built there from a picklable ``env_fn``;
* the learner waits on all workers at once (:func:`multiprocessing.connection.wait` on
  their pipes and process sentinels) with a deadline per env: ``step_timeout`` for a
  step, ``reset_timeout`` for a reset or the construction of an env;
* an env that raised (*error*), whose worker died (*crash*) or that did not answer in
  time (*timeout*) is killed with its worker's process group **and** every process group
  the env recorded in ``<run_dir>/.gymprecice/pids``
  (:func:`gymprecice.processes.kill_recorded_groups`), the failure is logged with the env
  index and the log tail (the solver's, from
  :attr:`gymprecice.errors.SolverError.log_tail`, else the worker's own output), and the
  env is started again and reset. Its partial episode ends as **truncated** with the
  failure in ``info["failure"]``; the other envs' results are untouched;
* exceptions never cross the pipe as such: the worker sends a plain description
  (:class:`EnvFailure`), so an unpicklable exception cannot break the pool;
* a failure budget (``max_failures_per_env`` within the last ``failure_window``
  episodes of an env) stops the run with :class:`FailureBudgetExceededError`, which lists
  every env's failures, instead of respawning a broken env forever. Errors that mean the
  configuration itself is wrong (``fatal_errors``: :class:`~gymprecice.errors.ConfigError`,
  :class:`~gymprecice.errors.PreciceNotInstalledError`) stop it at once;
* workers start concurrently (all constructed, then waited for) and resets run
  concurrently without any global lock.

Two facades put the pool behind the interfaces learners use: :class:`ResilientVectorEnv`
(Gymnasium 1.x ``VectorEnv``) here, and
:class:`gymprecice.sb3.ResilientSubprocVecEnv` (Stable-Baselines3 ``VecEnv``).

Autoreset: **same step** (:attr:`gymnasium.vector.AutoresetMode.SAME_STEP`, which is also
what Stable-Baselines3 does). When an episode ends, the step that ended it returns the
first observation of the next episode; the last observation and info of the ended
episode are in ``info["final_obs"]`` and ``info["final_info"]``. The same step resets a
failed env, so the learner never sees a broken env and never waits an extra step for a
reset. Options given to ``reset(options=...)`` stay in force for the env's automatic
resets until the next explicit reset, so an evaluation split
(``reset(options={"split": "eval"})``) is not silently dropped after the first episode.

The worker of env ``i`` writes its stdout and stderr to ``<log_dir>/env_<i>.log``; the
learner's process never blocks on anything but that wait with a deadline.
"""

from __future__ import annotations

import atexit
import contextlib
import ctypes
import logging
import math
import multiprocessing as mp
import os
import pickle
import select
import signal
import struct
import sys
import time
import traceback
import weakref
from collections import deque
from collections.abc import Callable, Generator, Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from multiprocessing.connection import Connection, wait
from multiprocessing.reduction import ForkingPickler
from pathlib import Path
from typing import Any

import cloudpickle
import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space, concatenate, create_empty_array, iterate

from gymprecice.errors import ConfigError, GymPreciceError, PreciceNotInstalledError
from gymprecice.processes import describe_returncode, kill_recorded_groups
from gymprecice.telemetry import Telemetry

__all__ = [
    "DEFAULT_FATAL_ERRORS",
    "EnvFailedError",
    "EnvFailure",
    "EnvPool",
    "FailureBudgetExceededError",
    "ResilientVectorEnv",
    "StepResult",
]

log = logging.getLogger(__name__)

#: Exceptions that mean every attempt would fail the same way: stop instead of respawning.
DEFAULT_FATAL_ERRORS: tuple[type[BaseException], ...] = (ConfigError, PreciceNotInstalledError)
DEFAULT_STEP_TIMEOUT = 900.0
DEFAULT_RESET_TIMEOUT = 1800.0
DEFAULT_CALL_TIMEOUT = 120.0
DEFAULT_CLOSE_TIMEOUT = 30.0
#: seconds a reply may take to arrive completely once its first bytes are there
MESSAGE_TIMEOUT_S = 60.0
#: lines of log kept in a failure report
TAIL_LINES = 40
_MAX_MESSAGE = 8000
_MAX_TAIL_BYTES = 64 * 1024


# ==========================================================================================
# Failures and errors
# ==========================================================================================


@dataclass(frozen=True)
class EnvFailure:
    """One env failure, as plain data: picklable, printable, and JSON-friendly.

    ``kind`` is ``"error"`` (the env raised), ``"crash"`` (its worker process died) or
    ``"timeout"`` (no answer within the step/reset timeout); ``phase`` is ``"start"``
    (building the env), ``"reset"``, ``"step"`` or ``"call"``. ``type`` is the exception's
    qualified name for errors. ``log_tail`` is the solver's log tail when the env raised a
    :class:`~gymprecice.errors.SolverError`, else the tail of the worker's own output.
    """

    env_index: int
    kind: str
    phase: str
    type: str
    message: str
    log_tail: str = ""
    log_file: str | None = None
    returncode: int | None = None
    solver: str | None = None
    traceback: str = ""
    episode: int = 0
    wall_time: float = 0.0
    killed_groups: tuple[int, ...] = ()

    def to_info(self) -> dict[str, Any]:
        """The failure as a dict for ``info["failure"]`` (plain types only)."""
        data = asdict(self)
        data["killed_groups"] = list(self.killed_groups)
        return data

    def describe(self, tail_lines: int = 10) -> str:
        """Human-readable, several lines: what failed, when, and the end of the log."""
        head = (
            f"env {self.env_index}, episode {self.episode}, {self.phase}: "
            f"{self.kind if self.kind != 'error' else self.type}: {self.message}"
        )
        tail = self.log_tail.rstrip().splitlines()[-tail_lines:] if tail_lines else []
        if tail:
            where = f" ({self.log_file})" if self.log_file else ""
            head += f"\n      log tail{where}:\n" + "\n".join("        " + t for t in tail)
        return head


class FailureBudgetExceededError(GymPreciceError, RuntimeError):
    """An env failed too often; the run stops instead of respawning it forever.

    ``failures`` maps each env index to its failures (:class:`EnvFailure`), oldest first.
    The vector env is closed (nothing of it is left running) when this is raised.
    """

    def __init__(self, message: str, failures: Mapping[int, Sequence[EnvFailure]]):
        self.failures = {int(k): list(v) for k, v in failures.items()}
        self.summary = message
        lines = [message, "Failures of every env (oldest first):"]
        for index in sorted(self.failures):
            items = self.failures[index]
            lines.append(f"  env {index}: {len(items)} failure(s)")
            lines += ["    - " + f.describe(tail_lines=5) for f in items[-10:]]
        super().__init__("\n".join(lines))

    def __reduce__(self):
        return (type(self), (self.summary, self.failures))


class EnvFailedError(GymPreciceError, RuntimeError):
    """An env failed in a way respawning cannot fix (a fatal error, a failing call).

    Raised when the original exception cannot be rebuilt in the learner's process;
    ``failure`` describes it.
    """

    def __init__(self, message: str, failure: EnvFailure | None = None):
        self.failure = failure
        super().__init__(message)

    def __reduce__(self):
        return (type(self), (str(self), self.failure))


# ==========================================================================================
# The worker process
# ==========================================================================================


def _qualified_name(cls: type) -> str:
    module = getattr(cls, "__module__", "") or ""
    return cls.__qualname__ if module == "builtins" else f"{module}.{cls.__qualname__}"


def describe_exception(
    exc: BaseException, fatal: tuple[type[BaseException], ...] = ()
) -> dict[str, Any]:
    """A picklable description of ``exc`` (what crosses the pipe instead of the exception).

    The exception itself is included, pickled, only when it survives a round trip here;
    the learner rebuilds it for calls whose caller expects the original type.
    """
    from gymprecice.errors import SolverError

    message = exc.summary if isinstance(exc, SolverError) else str(exc)
    desc: dict[str, Any] = {
        "type": _qualified_name(type(exc)),
        "message": message[:_MAX_MESSAGE] or type(exc).__name__,
        "traceback": "".join(traceback.format_exception(type(exc), exc, exc.__traceback__))[
            -_MAX_MESSAGE:
        ],
        "fatal": bool(fatal) and isinstance(exc, fatal),
        "pickled": None,
    }
    if isinstance(exc, SolverError):
        desc.update(
            log_tail=exc.log_tail,
            log_file=exc.log_file,
            returncode=exc.returncode,
            solver=exc.solver,
        )
    if _importable_here(type(exc)):
        try:
            data = pickle.dumps(exc)
            pickle.loads(data)
            desc["pickled"] = data
        except Exception:
            pass
    return desc


def _importable_here(cls: type) -> bool:
    """Whether pickle finds ``cls`` without importing anything (imports can be slow)."""
    module = sys.modules.get(getattr(cls, "__module__", "") or "")
    target: Any = module
    for part in cls.__qualname__.split("."):
        target = getattr(target, part, None)
    return module is not None and target is cls


def _run_dir_of(env: Any) -> str | None:
    """The env's run directory (where its pid registry lives), without preparing it.

    An Adapter prepares its run directory on first access of ``run_dir`` (a copy of the
    case, maybe a long prerun); the learner must know the directory *before* that, so that
    it can kill what a hung preparation started. Other envs may expose ``run_dir``.
    """
    base = getattr(env, "unwrapped", env)
    if "gymprecice.core" in sys.modules:
        from gymprecice.core import Adapter

        if isinstance(base, Adapter):
            return str(base.env_dir)
    try:
        value = getattr(base, "run_dir", None)
    except Exception:
        return None
    return os.fspath(value) if value else None


def _die_with_parent() -> None:
    """Ask Linux to send SIGTERM to this worker when its parent exits.

    The parent is the forkserver (which exits with the learner) or, with ``spawn``, the
    learner's thread that started the worker. The SIGTERM handler kills the env's
    recorded process groups, so a learner killed with SIGKILL leaves no solver behind.
    """
    if not sys.platform.startswith("linux"):
        return
    with contextlib.suppress(Exception):
        libc = ctypes.CDLL(None, use_errno=True)
        pr_set_pdeathsig = 1
        libc.prctl(pr_set_pdeathsig, int(signal.SIGTERM), 0, 0, 0)


def _redirect_output(log_path: str, index: int) -> None:
    fd = os.open(log_path, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
    os.dup2(fd, 1)
    os.dup2(fd, 2)
    os.close(fd)
    with contextlib.suppress(Exception):
        sys.stdout.reconfigure(line_buffering=True)  # type: ignore[union-attr]
    stamp = time.strftime("%Y-%m-%d %H:%M:%S")
    print(f"[gymprecice.vector] {stamp} env {index}: worker pid {os.getpid()} started", flush=True)


def _call(env: Any, data: tuple[str, tuple[Any, ...], dict[str, Any]]) -> Any:
    """Gymnasium's ``call``: call the attribute if it is callable, else return it."""
    name, args, kwargs = data
    attr = env.get_wrapper_attr(name)
    return attr(*args, **kwargs) if callable(attr) else attr


def _method(env: Any, data: tuple[str, tuple[Any, ...], dict[str, Any]]) -> Any:
    name, args, kwargs = data
    return env.get_wrapper_attr(name)(*args, **kwargs)


def _set(env: Any, data: tuple[str, Any]) -> None:
    name, value = data
    if hasattr(env, "set_wrapper_attr"):
        env.set_wrapper_attr(name, value)
    else:
        setattr(env, name, value)


def _has(env: Any, name: str) -> bool:
    try:
        env.get_wrapper_attr(name)
    except AttributeError:
        return False
    return True


def _wrapped(env: Any, name: tuple[str, str]) -> bool:
    """Whether a wrapper of ``env`` is (a subclass of) the class named ``(module, qualname)``.

    By name, so that asking (SB3's ``env_is_wrapped(Monitor)``) does not make the worker
    import the wrapper's library (SB3 and PyTorch: seconds and hundreds of MB per env).
    """
    current = env
    while isinstance(current, gym.Wrapper):
        if any((c.__module__, c.__qualname__) == tuple(name) for c in type(current).__mro__):
            return True
        current = current.env
    return False


def _apply(env: Any, data: tuple[Callable[..., Any], tuple[Any, ...], dict[str, Any]]) -> Any:
    fn, args, kwargs = data
    return fn(env, *args, **kwargs)


_COMMANDS: dict[str, Callable[[Any, Any], Any]] = {
    "step": lambda env, action: tuple(env.step(action)),
    "reset": lambda env, kw: tuple(env.reset(seed=kw["seed"], options=kw["options"])),
    "call": _call,
    "method": _method,
    "get": lambda env, name: env.get_wrapper_attr(name),
    "set": _set,
    "apply": _apply,
    "has": _has,
    "wrapped": _wrapped,
}


def _send(conn: Connection, reply: tuple[str, Any], fatal: tuple[type[BaseException], ...]):
    """Send a reply; a reply that cannot be pickled becomes an error description."""
    try:
        data = ForkingPickler.dumps(reply)
    except Exception as exc:
        problem = TypeError(f"the env's reply cannot be pickled to reach the learner: {exc!r}")
        data = ForkingPickler.dumps(("error", describe_exception(problem, fatal)))
    conn.send_bytes(data)


def _worker_main(
    index: int, payload: bytes, conn: Connection, log_path: str, environ: dict[str, str]
) -> None:
    """Body of an env worker process: build the env, then serve requests until closed.

    ``environ`` is the learner's environment when it started this worker: a forkserver
    child would otherwise see the environment the server was started with, and miss
    variables set since (``GYMPRECICE_PRECICE_LIBRARY``, MPI or license settings).
    """
    with contextlib.suppress(OSError):
        os.setsid()  # own process group: one signal reaches everything the env started
    os.environ.clear()
    os.environ.update(environ)
    _redirect_output(log_path, index)
    run_dir: str | None = None

    def on_term(signum: int, frame: Any) -> None:
        raise SystemExit(128 + signum)

    signal.signal(signal.SIGTERM, on_term)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the learner decides when to stop
    _die_with_parent()
    fatal: tuple[type[BaseException], ...] = ()
    env: Any = None
    try:
        env_fn, fatal = cloudpickle.loads(payload)
        started = time.perf_counter()
        try:
            env = env_fn()
            run_dir = _run_dir_of(env)
            ready = {
                "observation_space": env.observation_space,
                "action_space": env.action_space,
                "metadata": dict(getattr(env, "metadata", {}) or {}),
                "render_mode": getattr(env, "render_mode", None),
                "spec": getattr(env, "spec", None),
                "run_dir": run_dir,
                "pid": os.getpid(),
            }
            reply: tuple[str, Any] = ("ok", (ready, time.perf_counter() - started))
        except Exception as exc:
            traceback.print_exc()
            reply = ("error", describe_exception(exc, fatal))
        _send(conn, reply, fatal)
        if env is None:
            return
        while True:
            try:
                command, data = conn.recv()
            except EOFError:
                return
            if command == "close":
                try:
                    env.close()
                except Exception:
                    traceback.print_exc()
                env = None
                _send(conn, ("ok", (None, 0.0)), fatal)
                return
            started = time.perf_counter()
            try:
                value = _COMMANDS[command](env, data)
                reply = ("ok", (value, time.perf_counter() - started))
            except Exception as exc:
                traceback.print_exc()
                reply = ("error", describe_exception(exc, fatal))
            _send(conn, reply, fatal)
    except (SystemExit, KeyboardInterrupt, BrokenPipeError, EOFError):
        pass
    finally:
        # Leave nothing behind even when the learner vanished without closing us.
        if env is not None and run_dir:
            with contextlib.suppress(Exception):
                kill_recorded_groups(run_dir, grace=0.5)
        with contextlib.suppress(Exception):
            sys.stdout.flush()
            sys.stderr.flush()


# ==========================================================================================
# The pool (learner side)
# ==========================================================================================


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
class _Reply:
    kind: str  # "message" | "crash" | "timeout"
    value: Any = None


_CRASH = _Reply("crash")
_TIMEOUT = _Reply("timeout")


@dataclass
class _Outcome:
    value: Any = None
    failure: EnvFailure | None = None
    #: an exception raised by a called method (the env itself is fine)
    call_error: dict[str, Any] | None = None
    roundtrip: float = 0.0


class _Worker:
    """The learner's handle on one worker process."""

    def __init__(self, process: Any, conn: Connection, log_path: Path, log_offset: int):
        self.process = process
        self.conn = conn
        self.pid: int = process.pid
        self.sentinel: int = process.sentinel
        self.log_path = log_path
        self.log_offset = log_offset

    def kill(self, join_timeout: float = 5.0) -> int | None:
        """SIGKILL the worker's whole process group, reap it, close the pipe."""
        # Signal the group before reaping the leader: until then its pid cannot be reused.
        for kill, target in ((os.killpg, self.pid), (os.kill, self.pid)):
            with contextlib.suppress(ProcessLookupError, PermissionError):
                kill(target, signal.SIGKILL)
        self.process.join(join_timeout)
        with contextlib.suppress(Exception):
            self.conn.close()
        return self.process.exitcode

    def tail(self, lines: int = TAIL_LINES) -> str:
        """The end of what this worker (not its predecessors) wrote to its log."""
        try:
            with open(self.log_path, "rb") as f:
                size = f.seek(0, os.SEEK_END)
                f.seek(max(self.log_offset, size - _MAX_TAIL_BYTES))
                data = f.read()
        except OSError:
            return ""
        return "\n".join(data.decode("utf-8", errors="replace").splitlines()[-lines:])


@dataclass
class _Slot:
    """Everything the learner knows about env ``index`` across its workers' lives."""

    index: int
    failure_window: int
    worker: _Worker | None = None
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


_Job = Generator[float, _Reply, Any]


@dataclass
class _Batch:
    jobs: dict[int, _Job]
    waiting: dict[int, float] = field(default_factory=dict)
    results: dict[int, Any] = field(default_factory=dict)


def _readable(fds: Mapping[int, int], timeout: float | None) -> dict[int, set[int]]:
    """Wait until some of ``fds`` is readable (or hung up); ``{value: {ready fds}}``.

    ``multiprocessing.connection.wait`` builds a ``selectors`` object per call, which
    costs tens of microseconds per env and step in the learner's process; one
    ``poll(2)`` on the raw descriptors costs a few.
    """
    if not hasattr(select, "poll"):  # pragma: no cover - not Linux/macOS
        ready_fds = set(wait(list(fds), timeout))  # type: ignore[arg-type]
    else:
        poller = select.poll()
        for fd in fds:
            poller.register(fd, select.POLLIN)
        ms = None if timeout is None else math.ceil(timeout * 1000)
        while True:
            try:
                events = poller.poll(ms)
                break
            except InterruptedError:  # pragma: no cover - retried by Python already
                continue
        ready_fds = {fd for fd, _ in events}
    ready: dict[int, set[int]] = {}
    for fd in ready_fds:
        ready.setdefault(fds[fd], set()).add(fd)
    return ready


def _recv_bytes(fd: int, deadline: float) -> bytes:
    """One message framed like :meth:`multiprocessing.connection.Connection.send_bytes`.

    ``Connection.recv`` blocks until the whole message is there: a worker stopped (or
    swapped out for good) half-way through a large reply would block the learner
    forever. Here every read after the first waits with a deadline. Call only when ``fd``
    is readable. A worker sends exactly one reply per request, so reading ahead in
    large chunks never takes bytes of a next message.
    """
    buffer = bytearray()
    header: int | None = None  # 4, or 12 for messages of 2 GiB and more
    needed = 4
    first = True
    while len(buffer) < needed:
        if not first and not _readable({fd: fd}, max(0.0, deadline - time.monotonic())):
            raise TimeoutError("a message from an env worker stopped arriving half-way")
        first = False
        chunk = os.read(fd, max(needed - len(buffer), 1 << 16))
        if not chunk:
            raise EOFError
        buffer += chunk
        if header is None and len(buffer) >= 4:
            (size,) = struct.unpack_from("!i", buffer)
            if size != -1:
                header, needed = 4, 4 + size
            else:
                needed = 12
        if header is None and needed == 12 and len(buffer) >= 12:
            header, needed = 12, 12 + struct.unpack_from("!Q", buffer, 4)[0]
    return bytes(buffer[header:needed])


_LIVE_POOLS: weakref.WeakSet[EnvPool] = weakref.WeakSet()


@atexit.register
def _close_live_pools() -> None:
    for pool in list(_LIVE_POOLS):
        with contextlib.suppress(Exception):
            pool.close(timeout=2.0)


def _default_start_method() -> str:
    return "forkserver" if "forkserver" in mp.get_all_start_methods() else "spawn"


class EnvPool:
    """N env workers behind deadlines, respawning failed envs (see the module docstring).

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
        forked copy of a learner with threads (PyTorch) can deadlock.
    log_dir:
        Where each worker writes ``env_<i>.log`` (default ``gymprecice-runs/workers`` in
        the working directory, beside the Adapter's default run root).
    kill_grace:
        Seconds between SIGTERM and SIGKILL for the env's recorded process groups.
    daemon:
        Whether workers are daemonic (multiprocessing then also stops them at exit; a
        daemonic worker cannot start multiprocessing children of its own, ``subprocess``
        is fine).
    telemetry:
        Where timings and failures are recorded (default: a new
        :class:`~gymprecice.telemetry.Telemetry`).

    One pool is driven by one thread (the learner's). As with any ``forkserver`` or
    ``spawn`` pool, a script that builds one must guard its entry point with
    ``if __name__ == "__main__":``. With ``spawn``, a worker's parent is the thread that
    started it; if that thread ends, the worker gets SIGTERM (and cleans up).
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
        method = start_method or _default_start_method()
        if method == "fork":
            raise ValueError(
                "start_method='fork' is not supported: forking a learner that runs threads "
                "(PyTorch, logging) can deadlock the worker; use 'forkserver' or 'spawn'"
            )
        self._ctx = mp.get_context(method)
        if method == "forkserver":
            # Workers fork from a server that already imported numpy, gymnasium and us.
            self._ctx.set_forkserver_preload(["gymprecice.vector"])
        self.start_method = method
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
        live = [slot for slot in self._slots if slot.worker is not None]
        for slot in live:
            assert slot.worker is not None
            with contextlib.suppress(Exception):
                slot.worker.conn.send(("close", None))
        limit = self.close_timeout if timeout is None else timeout
        deadline = time.monotonic() + limit
        remaining = {slot.worker.sentinel for slot in live if slot.worker is not None}
        while remaining:
            left = deadline - time.monotonic()
            if left <= 0:
                break
            for handle in wait(list(remaining), left):
                remaining.discard(handle)  # type: ignore[arg-type]
        for slot in self._slots:
            if slot.worker is not None:
                slot.worker.kill()
                slot.worker = None
            if slot.run_dir:
                try:
                    kill_recorded_groups(slot.run_dir, grace=self.kill_grace)
                except OSError as exc:
                    log.debug("env %d: could not read its pid registry: %s", slot.index, exc)

    def __del__(self) -> None:
        with contextlib.suppress(Exception):
            if not self._closed:
                self.close(timeout=1.0)

    # -- jobs: one generator per env and operation -------------------------------------------
    # A job sends a request to its env's worker, then yields the deadline of the answer;
    # the driver (_finish) sends it back a _Reply: the message, a crash or a timeout.

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
    ) -> Generator[float, _Reply, tuple[Any, dict[str, Any]]]:
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

    def _spawn(self, slot: _Slot) -> Generator[float, _Reply, _Outcome]:
        """Start a worker for ``slot`` and wait until its env is built."""
        parent, child = self._ctx.Pipe(duplex=True)
        log_path = self.log_dir / f"env_{slot.index}.log"
        try:
            offset = log_path.stat().st_size
        except OSError:
            offset = 0
        process = self._ctx.Process(  # type: ignore[attr-defined]
            target=_worker_main,
            args=(slot.index, self._payloads[slot.index], child, str(log_path), dict(os.environ)),
            name=f"gymprecice-env-{slot.index}",
            daemon=self.daemon,
        )
        started = time.perf_counter()
        process.start()
        child.close()
        slot.worker = _Worker(process, parent, log_path, offset)
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
    ) -> Generator[float, _Reply, _Outcome]:
        assert slot.worker is not None
        try:
            slot.worker.conn.send((command, data))
        except (OSError, ValueError):
            # The worker is gone (broken pipe): let the driver see its sentinel.
            pass
        return (yield from self._await(slot, phase, timeout))

    def _await(
        self, slot: _Slot, phase: str, timeout: float | None
    ) -> Generator[float, _Reply, _Outcome]:
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
        pid = None
        if worker is not None:
            pid = worker.pid
            returncode = worker.kill()
            tail = worker.tail()
            log_file = str(worker.log_path)
        killed: list[int] = []
        if slot.run_dir:
            try:
                killed = kill_recorded_groups(slot.run_dir, grace=self.kill_grace)
            except OSError as exc:
                log.warning("env %d: could not read its pid registry: %s", slot.index, exc)
        desc = description or {}
        if kind == "crash":
            message = (
                f"env {slot.index}: its worker process (pid {pid}) died during '{phase}' "
                f"({describe_returncode(returncode) if returncode is not None else 'status unknown'})"
            )
            type_name = "WorkerCrashed"
        elif kind == "timeout":
            limit = f"{timeout:g} s" if timeout is not None else "its deadline"
            message = (
                f"env {slot.index}: no answer to '{phase}' within {limit}; the env looks "
                f"hung, so its worker (pid {pid}) and {len(killed)} recorded process group(s) "
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

    def _advance(self, batch: _Batch, index: int, reply: _Reply | None) -> None:
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
                fds: dict[int, int] = {}
                for index in batch.waiting:
                    worker = self._slots[index].worker
                    assert worker is not None
                    fds[worker.conn.fileno()] = index
                    fds[worker.sentinel] = index
                ready = _readable(fds, timeout)
                now = time.monotonic()
                for index in sorted(batch.waiting):
                    if index in ready:
                        reply = self._receive(self._slots[index], ready[index])
                    elif now >= batch.waiting[index]:
                        reply = _TIMEOUT
                    else:
                        continue
                    self._advance(batch, index, reply)
        except BaseException as exc:
            self._abort(batch, exc)
            if isinstance(exc, _FatalFailure):
                raise exc.rebuild() from None
            raise
        return batch.results

    def _receive(self, slot: _Slot, ready_fds: set[int]) -> _Reply:
        """Read the reply of a worker whose pipe or process sentinel became readable."""
        worker = slot.worker
        assert worker is not None
        fd = worker.conn.fileno()
        try:
            # Only the sentinel fired: the worker exited; a reply it sent first still counts.
            if fd in ready_fds or _readable({fd: 0}, 0.0):
                data = _recv_bytes(fd, time.monotonic() + MESSAGE_TIMEOUT_S)
                return _Reply("message", ForkingPickler.loads(data))
        except TimeoutError:
            return _TIMEOUT
        except (EOFError, OSError):
            return _CRASH
        except Exception as exc:  # the reply could not be unpickled here
            problem = TypeError(f"the reply of env {slot.index} cannot be unpickled: {exc!r}")
            return _Reply("message", ("error", describe_exception(problem)))
        return _CRASH

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
        original = _unpickle(self.description.get("pickled"))
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
            original = _unpickle(self.description.get("pickled"))
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


def _unpickle(data: bytes | None) -> BaseException | None:
    if not data:
        return None
    try:
        value = pickle.loads(data)
    except Exception:
        return None
    return value if isinstance(value, BaseException) else None


# ==========================================================================================
# Gymnasium facade
# ==========================================================================================


class ResilientVectorEnv(VectorEnv):
    """A Gymnasium 1.x ``VectorEnv`` on an :class:`EnvPool`; autoreset mode SAME_STEP.

    Follows :class:`gymnasium.vector.AsyncVectorEnv`'s conventions: ``reset(seed=s)`` seeds
    env ``i`` with ``s + i`` (a list gives one seed per env); ``options`` (one dict for all
    envs, or a list with one per env) reach every env's ``reset``, and
    ``options["reset_mask"]`` (a bool array) resets only some envs. Infos are batched
    with ``_key`` masks; when env ``i``'s episode ended in a step, ``infos["final_obs"][i]``
    and ``infos["final_info"]`` hold the ended episode's last observation and info, and
    the returned observation is the new episode's first. An episode cut short by an env
    failure has ``truncations[i] = True``, reward 0, and ``infos["failure"]`` (also in
    ``final_info``) describing it (:meth:`EnvFailure.to_info`). Options persist for the
    automatic resets of each env until the next explicit :meth:`reset`.

    Keyword arguments are those of :class:`EnvPool` (timeouts, failure budget, start
    method, log directory). ``telemetry`` (:class:`gymprecice.telemetry.Telemetry`)
    holds the timings; ``telemetry.summary()`` reports them.
    """

    def __init__(
        self, env_fns: Sequence[Callable[[], gym.Env]], *, copy: bool = True, **pool_kwargs: Any
    ) -> None:
        self.pool = EnvPool(env_fns, **pool_kwargs)
        self.copy = copy
        self.num_envs = self.pool.num_envs
        self.single_observation_space = self.pool.observation_space
        self.single_action_space = self.pool.action_space
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.metadata = dict(self.pool.metadata)
        self.metadata["autoreset_mode"] = AutoresetMode.SAME_STEP
        self.render_mode = self.pool.render_mode
        self._observations = create_empty_array(self.single_observation_space, self.num_envs)

    @property
    def telemetry(self) -> Telemetry:
        return self.pool.telemetry

    @property
    def failures(self) -> list[EnvFailure]:
        return self.pool.failures

    def reset(
        self,
        *,
        seed: int | Sequence[int | None] | None = None,
        options: Mapping[str, Any] | Sequence[Mapping[str, Any] | None] | None = None,
    ) -> tuple[Any, dict[str, Any]]:
        seeds = _per_env_seeds(seed, self.num_envs)
        per_env, mask = _per_env_options(options, self.num_envs)
        indices = [i for i in range(self.num_envs) if mask is None or mask[i]]
        results = self.pool.reset(seeds, per_env, indices)
        items, infos = [], {}
        for i in range(self.num_envs):
            if i in results:
                obs, info = results[i]
                infos = self._add_info(infos, info, i)
            else:
                obs = self.pool._slots[i].last_obs
            items.append(obs)
        self._observations = concatenate(self.single_observation_space, items, self._observations)
        return self._output(self._observations), infos

    def step_async(self, actions: Any) -> None:
        self.pool.step_async(list(iterate(self.action_space, actions)))

    def step_wait(self) -> tuple[Any, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        results = self.pool.step_wait()
        infos: dict[str, Any] = {}
        for i, result in enumerate(results):
            info = dict(result.info)
            if result.done:
                info["final_obs"] = result.final_obs
                info["final_info"] = result.final_info or {}
            infos = self._add_info(infos, info, i)
        self._observations = concatenate(
            self.single_observation_space, [r.obs for r in results], self._observations
        )
        return (
            self._output(self._observations),
            np.array([r.reward for r in results], dtype=np.float64),
            np.array([r.terminated for r in results], dtype=np.bool_),
            np.array([r.truncated for r in results], dtype=np.bool_),
            infos,
        )

    def step(self, actions: Any) -> tuple[Any, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        self.step_async(actions)
        return self.step_wait()

    def call(self, name: str, *args: Any, **kwargs: Any) -> tuple[Any, ...]:
        """Call method ``name`` (or read attribute ``name``) of every env."""
        return tuple(self.pool.call("call", (name, args, kwargs)))

    def get_attr(self, name: str) -> tuple[Any, ...]:
        return tuple(self.pool.call("get", name))

    def set_attr(self, name: str, values: Any) -> None:
        if not isinstance(values, (list, tuple)):
            values = [values] * self.num_envs
        if len(values) != self.num_envs:
            raise ValueError(
                f"values must be one value or {self.num_envs} (one per env), got {len(values)}"
            )
        for i, value in enumerate(values):
            self.pool.call("set", (name, value), [i])

    def render(self) -> tuple[Any, ...] | None:
        return self.call("render")

    def close_extras(self, **kwargs: Any) -> None:
        pool = self.__dict__.get("pool")
        if pool is not None:
            pool.close(**kwargs)

    def _output(self, observations: Any) -> Any:
        import copy as _copy

        return _copy.deepcopy(observations) if self.copy else observations


def _per_env_seeds(seed: int | Sequence[int | None] | None, n: int) -> list[int | None]:
    if seed is None:
        return [None] * n
    if isinstance(seed, (int, np.integer)):
        return [int(seed) + i for i in range(n)]
    seeds = list(seed)
    if len(seeds) != n:
        raise ValueError(f"expected one seed or {n} seeds, got {len(seeds)}")
    return seeds


def _per_env_options(
    options: Mapping[str, Any] | Sequence[Mapping[str, Any] | None] | None, n: int
) -> tuple[list[dict[str, Any] | None], np.ndarray | None]:
    """Split Gymnasium's reset options into one dict per env, and the reset mask."""
    if options is None:
        return [None] * n, None
    if isinstance(options, Mapping):
        common = dict(options)
        mask = common.pop("reset_mask", None)
        if mask is not None:
            mask = np.asarray(mask)
            if mask.shape != (n,) or mask.dtype != np.bool_ or not mask.any():
                raise ValueError(
                    f"options['reset_mask'] must be a bool array of shape ({n},) with at "
                    "least one True value"
                )
        return [dict(common) for _ in range(n)], mask
    per_env = [dict(o) if o is not None else None for o in options]
    if len(per_env) != n:
        raise ValueError(f"expected one options dict or {n} (one per env), got {len(per_env)}")
    return per_env, None
