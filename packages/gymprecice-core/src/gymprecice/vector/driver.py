"""The pool's driver: run the jobs of a batch at once, each against its deadline.

It starts every job, waits on all hosts together through the backend until the earliest
deadline, hands each job its reply (or a timeout) and, when an exception escapes a job
(budget spent, fatal error, Ctrl-C), closes every job and the pool. It is apart from
:mod:`.pool` because it is the same loop for every operation and every backend;
:class:`~gymprecice.vector.pool.EnvPool` inherits it.
"""

from __future__ import annotations

import contextlib
import logging
import math
import time
from typing import Any

import gymnasium as gym

from gymprecice.vector.contract import TIMEOUT, Backend, Reply
from gymprecice.vector.failures import FailureBudgetExceededError
from gymprecice.vector.restarts import FatalFailure
from gymprecice.vector.slots import Batch, Job, Slot

log = logging.getLogger("gymprecice.vector")


class BatchDriver:
    """The driver of :class:`~gymprecice.vector.pool.EnvPool` (a base class of it)."""

    backend: Backend
    close_timeout: float
    _closed: bool
    _pending: Batch | None
    _slots: list[Slot]

    def close(self, timeout: float | None = None) -> None:
        raise NotImplementedError

    def _check_idle(self) -> None:
        if self._closed:
            raise gym.error.ClosedEnvironmentError("the vector env is closed")
        if self._pending is not None:
            raise gym.error.AlreadyPendingCallError(
                "a step is in flight: call step_wait() first", "step"
            )

    def _run(self, jobs: dict[int, Job]) -> dict[int, Any]:
        return self._finish(self._start(jobs))

    def _start(self, jobs: dict[int, Job]) -> Batch:
        batch = Batch(jobs)
        try:
            for index in jobs:
                self._advance(batch, index, None)
        except BaseException as exc:
            self._abort(batch, exc)
            if isinstance(exc, FatalFailure):
                raise exc.rebuild() from None
            raise
        return batch

    def _advance(self, batch: Batch, index: int, reply: Reply | None) -> None:
        try:
            deadline = batch.jobs[index].send(reply)  # type: ignore[arg-type]
        except StopIteration as stop:
            batch.waiting.pop(index, None)
            batch.results[index] = stop.value
            return
        batch.waiting[index] = deadline

    def _finish(self, batch: Batch) -> dict[int, Any]:
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
            if isinstance(exc, FatalFailure):
                raise exc.rebuild() from None
            raise
        return batch.results

    def _abort(self, batch: Batch, exc: BaseException) -> None:
        """An exception escaped a job (budget spent, fatal error, Ctrl-C): close all."""
        for job in batch.jobs.values():
            with contextlib.suppress(Exception):
                job.close()
        if not isinstance(exc, (FailureBudgetExceededError, FatalFailure)):
            log.warning("vector env interrupted by %s; closing it", type(exc).__name__)
        self.close(timeout=min(self.close_timeout, 5.0))
