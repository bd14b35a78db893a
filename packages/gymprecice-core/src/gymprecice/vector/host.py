"""The env side of the pool, wherever the env is hosted (a worker process, a Ray actor).

A host builds the env from its pickled ``env_fn`` and answers one request at a time with
``("ok", (value, seconds))`` or ``("error", description)``; the backends only carry these
requests and replies.
"""

from __future__ import annotations

import os
import sys
import time
import traceback
from collections.abc import Callable
from typing import Any

import cloudpickle
import gymnasium as gym

from gymprecice.vector.failures import describe_exception

Reply = tuple[str, Any]


def _run_dir_of(env: Any) -> str | None:
    """The env's run directory (where its pid registry lives), without preparing it.

    An Adapter prepares its run directory on first access of ``run_dir`` (a copy of the
    case, maybe a long prerun); the learner must know the directory *before* that, so that
    it can kill what a hung preparation started. Other envs may expose ``run_dir``.
    """
    base = getattr(env, "unwrapped", env)
    if "gymprecice.env.core" in sys.modules:
        from gymprecice.env.core import Adapter

        if isinstance(base, Adapter):
            return str(base.env_dir)
    try:
        value = getattr(base, "run_dir", None)
    except Exception:
        return None
    return os.fspath(value) if value else None


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


COMMANDS: dict[str, Callable[[Any, Any], Any]] = {
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


def build(payload: bytes) -> tuple[Any, Reply, tuple[type[BaseException], ...]]:
    """Build the env from its payload; ``(env or None, the first reply, fatal errors)``.

    The first reply tells the learner the env's spaces and where its run directory is
    (before anything prepared it, so that the learner can kill what a hung preparation
    started).
    """
    env_fn, fatal = cloudpickle.loads(payload)
    started = time.perf_counter()
    try:
        env = env_fn()
        ready = {
            "observation_space": env.observation_space,
            "action_space": env.action_space,
            "metadata": dict(getattr(env, "metadata", {}) or {}),
            "render_mode": getattr(env, "render_mode", None),
            "spec": getattr(env, "spec", None),
            "run_dir": _run_dir_of(env),
            "pid": os.getpid(),
        }
        return env, ("ok", (ready, time.perf_counter() - started)), fatal
    except Exception as exc:
        traceback.print_exc()
        return None, ("error", describe_exception(exc, fatal)), fatal


def handle(env: Any, command: str, data: Any, fatal: tuple[type[BaseException], ...]) -> Reply:
    """Run one request on the env; an exception becomes a description, never escapes."""
    started = time.perf_counter()
    try:
        value = COMMANDS[command](env, data)
        return "ok", (value, time.perf_counter() - started)
    except Exception as exc:
        traceback.print_exc()
        return "error", describe_exception(exc, fatal)


def close(env: Any) -> None:
    """Close the env; a failing ``close()`` is printed to the host's log, not raised."""
    try:
        env.close()
    except Exception:
        traceback.print_exc()
