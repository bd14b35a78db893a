"""What the pool does when an env fails: kill, record, log, and restart or stop.

An env that raised, whose host died or that did not answer in time is killed with every
process group it recorded, its failure is recorded (``info["failure"]``, telemetry and a
line of ``failures.jsonl``) and logged with its log tail, and it is restarted, unless
the failure budget is spent (:class:`~gymprecice.vector.failures.FailureBudgetExceededError`)
or the error is fatal. It is apart from :mod:`.pool` because this restart policy is the
pool's one decision about failures, the same for every backend.
"""

from __future__ import annotations

import contextlib
import json
import logging
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gymprecice.env.exit_status import describe_returncode
from gymprecice.vector.contract import Backend
from gymprecice.vector.failures import (
    TAIL_LINES,
    EnvFailedError,
    EnvFailure,
    FailureBudgetExceededError,
    unpickle_exception,
)
from gymprecice.vector.slots import Slot
from gymprecice.vector.telemetry import Telemetry

log = logging.getLogger("gymprecice.vector")

#: every failure of a pool's envs, one JSON line each (``EnvFailure.to_info``), in its
#: ``log_dir``: what a run's restarts were, after it ended (appended to across runs)
FAILURES_FILE = "failures.jsonl"


class FailureHandling:
    """Failure handling of :class:`~gymprecice.vector.pool.EnvPool` (a base class of it)."""

    backend: Backend
    telemetry: Telemetry
    log_dir: Path
    kill_grace: float
    max_failures_per_env: int
    failure_window: int
    _slots: list[Slot]

    def _fail(
        self,
        slot: Slot,
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
            raise FatalFailure(failure, desc)
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

    def _derived_seed(self, slot: Slot) -> int | None:
        """Seed of a respawned env's first reset: reproducible from the env's own seed."""
        if slot.seed is None:
            return None
        state = np.random.SeedSequence([int(slot.seed) % 2**63, len(slot.failures)])
        return int(state.generate_state(1, dtype=np.uint32)[0])


class FatalFailure(Exception):
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
class CallFailed:
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
