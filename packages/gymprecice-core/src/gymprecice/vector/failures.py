"""What the pool knows of a failure: plain, picklable data and the errors that stop a run.

Exceptions never cross from an env to the learner as such: an env's host sends a plain
description (:func:`describe_exception`), so an exception that cannot be pickled (or
whose class the learner cannot import) cannot break the pool.
"""

from __future__ import annotations

import pickle
import sys
import traceback
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from typing import Any

from gymprecice.plugin.errors import ConfigError, GymPreciceError, PreciceNotInstalledError

#: Exceptions that mean every attempt would fail the same way: stop instead of respawning.
DEFAULT_FATAL_ERRORS: tuple[type[BaseException], ...] = (ConfigError, PreciceNotInstalledError)
#: lines of log kept in a failure report
TAIL_LINES = 40
_MAX_MESSAGE = 8000


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
    from gymprecice.plugin.errors import SolverError

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


def unpickle_exception(data: bytes | None) -> BaseException | None:
    """The exception a worker pickled into its failure description (``None``: none was, or
    it does not unpickle here)."""
    if not data:
        return None
    try:
        value = pickle.loads(data)
    except Exception:
        return None
    return value if isinstance(value, BaseException) else None
