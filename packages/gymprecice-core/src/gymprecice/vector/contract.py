"""The contract between the pool and its backends: the data that crosses it.

:class:`~gymprecice.vector.pool.EnvPool` decides (deadlines, respawn, failure budget); a
backend (:mod:`gymprecice.vector.local`, :mod:`gymprecice.vector.ray`) only starts hosts,
carries requests and waits for replies. Both sides read this module, and it reads neither:
what a backend must offer (:class:`Backend`, :class:`Host`) and what it hands back for each
request (:class:`Reply`: the env's message, or :data:`CRASH` / :data:`TIMEOUT`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

from gymprecice.vector.failures import TAIL_LINES


@dataclass
class Reply:
    """What a backend got from an env's host: a message, or that it crashed or timed out."""

    kind: str  # "message" | "crash" | "timeout"
    value: Any = None


CRASH = Reply("crash")
TIMEOUT = Reply("timeout")


class Host(Protocol):
    """The pool's handle on one life of one env (a worker process, a Ray actor)."""

    pid: int | None
    log_path: Path

    @property
    def where(self) -> str:
        """Where the env ran, for failure messages (``worker process (pid 12)``)."""
        ...

    def send(self, command: str, data: Any) -> None:
        """Send one request; its reply comes through :meth:`Backend.wait`."""
        ...

    def kill(self) -> int | None:
        """Stop the host at once; its exit status when known."""
        ...

    def tail(self, lines: int = TAIL_LINES) -> str:
        """The end of the host's own output (for failure reports)."""
        ...


class Backend(Protocol):
    """Where envs live: start, send (on the host), wait, kill, clean up."""

    def spawn(self, index: int, payload: bytes, log_path: Path) -> Host:
        """Start a host that builds env ``index``; its first reply says it is ready."""
        ...

    def wait(self, hosts: Mapping[int, Host], timeout: float | None) -> dict[int, Reply]:
        """Wait up to ``timeout`` seconds for replies of ``hosts``; the ones that came."""
        ...

    def cleanup(self, run_dir: str | None, host: Host | None, grace: float) -> list[int]:
        """Kill what the env recorded in its run directory, on the machine it ran on."""
        ...

    def close(self, hosts: Sequence[Host], timeout: float) -> None:
        """Ask the hosts to close their envs; wait up to ``timeout`` for them to end."""
        ...

    def shutdown(self) -> None:
        """Release what the backend holds once the pool is closed."""
        ...
