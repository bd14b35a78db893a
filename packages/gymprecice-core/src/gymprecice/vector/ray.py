"""The Ray backend: each env in a Ray actor, on any node of a cluster.

Imported only when a pool is built with ``backend="ray"`` (or a :class:`RayBackend`); it
needs ``pip install "gymprecice-core[ray]"`` on the driver and on every node.

One env = one actor that asks for the CPUs its solvers use (:func:`solver_cpus`). The
actor works in a node-local directory (a relative ``run_root`` lands there) and hosts the
env exactly as the local backend does: in a worker process of its own, on its node. That
worker is what makes cleanup reach the node where the processes ran:

* the worker dies with the actor (``PR_SET_PDEATHSIG``) and, dying, kills every process
  group its env recorded in ``<run_dir>/.gymprecice/pids``. So a killed actor, or one
  whose node was lost (its raylet gone, so its workers exit), leaves no solver behind;
* after a failure the driver also runs a small cleanup task pinned to the actor's node
  (:class:`~ray.util.scheduling_strategies.NodeAffinitySchedulingStrategy`): it kills the
  worker's process group and the recorded groups, and reads the log tail for the report.

The pool's contract is untouched: deadlines are the driver's (an actor that does not
answer in time is killed with ``ray.kill``), a dead actor or node is a *crash* (one
failure per env on it; the report names a lost node as such), and a respawned env is a
new actor that Ray places on any node with room. Where no node has room (a lost node's
envs on a full cluster) the actor waits for one; the driver says so after
``PLACEMENT_NOTICE_S``. Logs come back to the driver: the tail of each failure in its
report, and the whole log of each env into ``<log_dir>/env_<i>.log`` when the pool closes.
"""

from __future__ import annotations

import contextlib
import functools
import logging
import os
import signal
import tempfile
import time
import uuid
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import cloudpickle
import ray
from ray.exceptions import GetTimeoutError, RayActorError, RayError, TaskUnschedulableError
from ray.util.scheduling_strategies import NodeAffinitySchedulingStrategy

from gymprecice.env.pidregistry import kill_recorded_groups
from gymprecice.vector.contract import CRASH, Reply
from gymprecice.vector.failures import TAIL_LINES
from gymprecice.vector.local import LocalBackend

__all__ = ["RayBackend", "solver_cpus"]

log = logging.getLogger("gymprecice.vector")

#: seconds the driver waits for a node-local cleanup task (a lost node never answers)
NODE_TASK_TIMEOUT_S = 30.0
#: seconds a new actor may wait for a node with room before the driver says it waits
PLACEMENT_NOTICE_S = 60.0
#: how often the driver looks whether such an actor found a node
_PLACEMENT_POLL_S = 5.0
#: where an actor works when neither the backend nor GYMPRECICE_NODE_DIR says
_NODE_DIR_ENV = "GYMPRECICE_NODE_DIR"


def solver_cpus(env_fn: Callable[..., Any]) -> int | None:
    """CPUs the solvers of ``env_fn``'s env use, when its configuration says (else None).

    Looks for a :class:`~gymprecice.config.GymPreciceConfig` among the arguments of a
    ``functools.partial`` and adds up its solvers' ``np`` options (1 each by default).
    An ``env_fn`` with a ``num_cpus`` attribute says it directly.
    """
    declared = getattr(env_fn, "num_cpus", None)
    if declared is not None:
        return int(declared)
    if not isinstance(env_fn, functools.partial):
        return None
    from gymprecice.env.config import GymPreciceConfig

    for value in (*env_fn.args, *env_fn.keywords.values()):
        if isinstance(value, GymPreciceConfig):
            return value.solver_cpus
    return None


class EnvActor:
    """One env on one node: a local worker process behind a Ray actor.

    Calls are served one at a time; the driver never waits on an actor without a
    deadline, and kills it when one passes.
    """

    def __init__(
        self, index: int, payload: bytes, node_dir: str | None, environ: dict[str, str]
    ) -> None:
        os.environ.update(environ)
        base = Path(node_dir or os.environ.get(_NODE_DIR_ENV) or tempfile.gettempdir())
        self.dir = base / "gymprecice-ray" / f"env_{index}-{uuid.uuid4().hex[:8]}"
        self.dir.mkdir(parents=True, exist_ok=True)
        os.chdir(self.dir)  # a relative run_root is node-local; the actor owns its process
        self.log_path = self.dir / f"env_{index}.log"
        self.backend = LocalBackend()
        self.worker = self.backend.spawn(index, payload, self.log_path)

    def where(self) -> dict[str, Any]:
        """Node id, worker pid and log path: what the driver needs to clean up there."""
        return {
            "node_id": ray.get_runtime_context().get_node_id(),
            "pid": self.worker.pid,
            "actor_pid": os.getpid(),
            "log_path": str(self.log_path),
        }

    def request(self, command: str | None, data: Any = None) -> Reply:
        """Send one request to the worker (``None``: just wait for its first reply)."""
        if command is not None:
            self.worker.send(command, data)
        while True:
            replies = self.backend.wait({0: self.worker}, None)
            if 0 in replies:
                return replies[0]

    def close(self, timeout: float) -> str:
        """Close the env, kill what is left; the whole log, for the driver."""
        self.backend.close([self.worker], timeout)
        self.worker.kill()
        try:
            return self.log_path.read_text(errors="replace")
        except OSError:
            return ""


def _clean_node(pid: int | None, run_dir: str | None, grace: float, log_path: str | None):
    """On the env's node: kill its worker's group and recorded groups; read its log tail."""
    if pid:
        for kill, target in ((os.killpg, pid), (os.kill, pid)):
            with contextlib.suppress(ProcessLookupError, PermissionError):
                kill(target, signal.SIGKILL)
    killed = kill_recorded_groups(run_dir, grace=grace) if run_dir else []
    tail = ""
    if log_path:
        with contextlib.suppress(OSError):
            with open(log_path, "rb") as f:
                f.seek(max(0, f.seek(0, os.SEEK_END) - 64 * 1024))
                lines = f.read().decode("utf-8", errors="replace").splitlines()
            tail = "\n".join(lines[-TAIL_LINES:])
    return killed, tail


_clean_node_task = ray.remote(num_cpus=0, max_retries=0)(_clean_node)


class RayHost:
    """The driver's handle on one actor (one life of one env)."""

    def __init__(self, actor: Any, index: int, log_path: Path, asks: str = "") -> None:
        self.actor = actor
        self.index = index
        self.log_path = log_path
        self.asks = asks  # what it asks of a node, for the notice that none has room
        self._where_ref = actor.where.remote()
        self._where: dict[str, Any] | None = None
        self.ref = actor.request.remote(None)
        self._tail = ""
        self.log_returned = False  # the whole log came back (at close): no tail to add
        self.spawned = time.monotonic()
        self.placement_known = False  # it runs on a node, or the driver said it waits
        self.node_lost = False  # its node is gone (a cleanup task there was unschedulable)

    def _info(self) -> dict[str, Any]:
        if self._where is None:
            try:
                self._where = ray.get(self._where_ref, timeout=NODE_TASK_TIMEOUT_S)
            except (RayError, GetTimeoutError):
                self._where = {}
        return self._where

    @property
    def node_id(self) -> str | None:
        """Hex id of the node the actor runs on (None if it died before saying)."""
        return self._info().get("node_id")

    @property
    def pid(self) -> int | None:
        """Pid of the env's worker process on its node."""
        return self._info().get("pid")

    @property
    def where(self) -> str:
        node = (self.node_id or "unknown")[:12]
        lost = "lost node" if self.node_lost else "node"
        return f"Ray actor on {lost} {node} (worker pid {self.pid})"

    def send(self, command: str, data: Any) -> None:
        self.ref = self.actor.request.remote(command, data)

    def kill(self) -> int | None:
        """Kill the actor, then its worker's process group on its node."""
        with contextlib.suppress(Exception):
            ray.kill(self.actor, no_restart=True)
        info = self._info()
        _, self._tail = self.run_on_node(info.get("pid"), None, 0.0, info.get("log_path"))
        if self._tail and not self.log_returned:
            with contextlib.suppress(OSError), open(self.log_path, "a") as f:
                f.write(self._tail + "\n")
        return None

    def tail(self, lines: int = TAIL_LINES) -> str:
        return "\n".join(self._tail.splitlines()[-lines:])

    def run_on_node(
        self, pid: int | None, run_dir: str | None, grace: float, log_path: str | None
    ) -> tuple[list[int], str]:
        """Run :func:`_clean_node` on the actor's node; nothing if that node is gone."""
        node = self.node_id
        if node is None or self.node_lost:
            return [], ""
        task = _clean_node_task.options(
            scheduling_strategy=NodeAffinitySchedulingStrategy(node, soft=False)
        )
        try:
            return ray.get(task.remote(pid, run_dir, grace, log_path), timeout=NODE_TASK_TIMEOUT_S)
        except (RayError, GetTimeoutError) as exc:
            # unschedulable: Ray knows the node is gone (its solvers died with it)
            self.node_lost = isinstance(exc, TaskUnschedulableError)
            log.info(
                "env %d: no cleanup on node %s (%s)", self.index, node[:12], type(exc).__name__
            )
            return [], ""


class RayBackend:
    """Start, send, wait, kill, clean up: envs as Ray actors on a cluster.

    Parameters
    ----------
    address:
        Passed to ``ray.init`` when Ray is not initialised yet (``"auto"``: the cluster
        this machine joined; ``None``: a new local one). An initialised Ray is used as is.
    num_cpus:
        CPUs each env's actor asks for; default :func:`solver_cpus` of its ``env_fn``,
        else 1.
    resources:
        Custom resources each actor asks for (``{"cfd": 1}`` to keep envs off the head).
    node_dir:
        Node-local directory the actors work in (default ``$GYMPRECICE_NODE_DIR`` on the
        node, else its temporary directory).
    actor_options:
        More options for ``EnvActor.options`` (``scheduling_strategy``, ``runtime_env``,
        ``memory``).
    forward_env:
        Environment variables of the driver that reach the envs (by prefix).
    """

    def __init__(
        self,
        address: str | None = None,
        *,
        num_cpus: float | None = None,
        resources: Mapping[str, float] | None = None,
        node_dir: str | None = None,
        actor_options: Mapping[str, Any] | None = None,
        forward_env: Sequence[str] = ("GYMPRECICE_",),
    ) -> None:
        self._owns_ray = not ray.is_initialized()
        if self._owns_ray:
            ray.init(address=address, log_to_driver=False)
        self.num_cpus = num_cpus
        self.resources = dict(resources or {})
        self.node_dir = node_dir
        self.actor_options = dict(actor_options or {})
        self.forward_env = tuple(forward_env)
        self._actor_class = ray.remote(max_restarts=0, max_task_retries=0)(EnvActor)
        self._cpus: dict[int, float] = {}

    def spawn(self, index: int, payload: bytes, log_path: Path) -> RayHost:
        if index not in self._cpus:
            self._cpus[index] = self.num_cpus or solver_cpus(cloudpickle.loads(payload)[0]) or 1
        environ = {k: v for k, v in os.environ.items() if k.startswith(self.forward_env)}
        options = {
            "num_cpus": self._cpus[index],
            "resources": self.resources,
            **self.actor_options,
        }
        actor = self._actor_class.options(**options).remote(index, payload, self.node_dir, environ)
        asks = f"{self._cpus[index]:g} CPU(s)" + "".join(
            f", {v:g} {k}" for k, v in self.resources.items()
        )
        return RayHost(actor, index, log_path, asks)

    def wait(self, hosts: Mapping[int, RayHost], timeout: float | None) -> dict[int, Reply]:
        """Wait up to ``timeout`` for the pending requests of ``hosts``; those answered
        (none, earlier, while an actor waits for a node: see :meth:`_note_unplaced`)."""
        if self._note_unplaced(hosts.values()):
            timeout = _PLACEMENT_POLL_S if timeout is None else min(timeout, _PLACEMENT_POLL_S)
        refs = {host.ref: index for index, host in hosts.items()}
        ready, rest = ray.wait(list(refs), num_returns=1, timeout=timeout)
        if ready and rest:
            more, _ = ray.wait(rest, num_returns=len(rest), timeout=0)
            ready += more
        replies: dict[int, Reply] = {}
        for ref in ready:
            try:
                replies[refs[ref]] = ray.get(ref)
            except RayActorError:
                replies[refs[ref]] = CRASH  # the actor died, or its node did
            except RayError as exc:
                log.warning("env %d: Ray failed its request: %s", refs[ref], exc)
                replies[refs[ref]] = CRASH
        return replies

    def _note_unplaced(self, hosts: Iterable[RayHost]) -> bool:
        """Say once of each actor not started ``PLACEMENT_NOTICE_S`` after it was asked
        for that it waits (Ray waits for a node with room for ever, silently); whether any
        such notice is still to come."""
        watching = False
        for host in hosts:
            if host.placement_known:
                continue
            host.placement_known = bool(ray.wait([host._where_ref], timeout=0)[0])
            if host.placement_known:
                continue
            waited = time.monotonic() - host.spawned
            if waited < PLACEMENT_NOTICE_S:
                watching = True
                continue
            host.placement_known = True  # said once
            free = ray.available_resources().get("CPU", 0.0)
            log.warning(
                "env %d: its Ray actor has not started after %.0f s (it asks for %s; the "
                "cluster has %g CPU(s) free): it starts once a node has room for it, when "
                "one joins or other work ends. A lost node's envs wait so on a full cluster.",
                host.index,
                waited,
                host.asks,
                free,
            )
        return watching

    def cleanup(self, run_dir: str | None, host: RayHost | None, grace: float) -> list[int]:
        """Kill the env's recorded process groups, on the node where it ran."""
        if host is None or run_dir is None:
            return []
        killed, _ = host.run_on_node(None, run_dir, grace, None)
        return killed

    def close(self, hosts: Sequence[RayHost], timeout: float) -> None:
        """Close every env on its node; append each env's whole log to the driver's."""
        refs = {host.actor.close.remote(timeout): host for host in hosts}
        ready, _ = ray.wait(list(refs), num_returns=len(refs), timeout=timeout + 5.0)
        for ref in ready:
            with contextlib.suppress(RayError, OSError):
                text = ray.get(ref)
                with open(refs[ref].log_path, "a") as f:
                    f.write(text)
                refs[ref].log_returned = True

    def shutdown(self) -> None:
        """Disconnect from Ray if this backend connected (a user's ``ray.init`` stays)."""
        if self._owns_ray and ray.is_initialized():
            ray.shutdown()
