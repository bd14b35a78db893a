"""The pool's jobs: one generator per env and operation (start, reset, step, call).

A job sends a request to its env's host, yields the deadline of the answer and gets
back a :class:`~gymprecice.vector.contract.Reply`; the driver (:mod:`.driver`) runs
them all at once. Here is what each operation does with its answers: same-step
autoreset, respawning an env and resetting it again after a failure, retrying a call
once. It is apart from :mod:`.pool` so that the pool's face (construction, the public
API, closing) reads on its own; :class:`~gymprecice.vector.pool.EnvPool` inherits it.
"""

from __future__ import annotations

import math
import time
from collections.abc import Generator
from pathlib import Path
from typing import Any

from gymprecice.vector.contract import Backend, Reply
from gymprecice.vector.failures import EnvFailure
from gymprecice.vector.restarts import CallFailed, FailureHandling
from gymprecice.vector.slots import Job, Outcome, Slot, StepResult
from gymprecice.vector.telemetry import Telemetry


class EnvJobs(FailureHandling):
    """The jobs of :class:`~gymprecice.vector.pool.EnvPool` (a base class of it)."""

    backend: Backend
    telemetry: Telemetry
    log_dir: Path
    step_timeout: float | None
    reset_timeout: float | None
    call_timeout: float | None
    _payloads: list[bytes]

    def _start_job(self, slot: Slot) -> Job:
        while True:
            outcome = yield from self._spawn(slot)
            if outcome.failure is None:
                return outcome.value

    def _reset_job(self, slot: Slot, seed: int | None, options: dict[str, Any] | None) -> Job:
        if slot.episode_active:
            slot.history.append(False)  # the episode ended, just not by itself
        slot.episode_active = False
        slot.pending_failure = None
        slot.seed = seed
        slot.options = options
        obs, info = yield from self._episode_start(slot, seed, options)
        return obs, info

    def _step_job(self, slot: Slot, action: Any) -> Job:
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

    def _call_job(self, slot: Slot, command: str, data: Any) -> Job:
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
                return CallFailed(slot.index, command, data, outcome.call_error)
            if outcome.failure is None:
                return outcome.value[0]
            last = outcome.failure
            if was_active:
                # The episode died with the worker: the next step reports it (truncated).
                slot.pending_failure = last
        assert last is not None
        return CallFailed(slot.index, command, data, None, last)

    def _episode_start(
        self, slot: Slot, seed: int | None, options: dict[str, Any] | None
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

    def _spawn(self, slot: Slot) -> Generator[float, Reply, Outcome]:
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
        self, slot: Slot, phase: str, command: str, data: Any, timeout: float | None
    ) -> Generator[float, Reply, Outcome]:
        assert slot.worker is not None
        slot.worker.send(command, data)
        return (yield from self._await(slot, phase, timeout))

    def _await(
        self, slot: Slot, phase: str, timeout: float | None
    ) -> Generator[float, Reply, Outcome]:
        sent = time.perf_counter()
        deadline = math.inf if timeout is None else time.monotonic() + timeout
        reply = yield deadline
        roundtrip = time.perf_counter() - sent
        description: dict[str, Any] | None = None
        if reply.kind == "message":
            tag, value = reply.value
            if tag == "ok":
                return Outcome(value=value, roundtrip=roundtrip)
            description = value
            if phase == "call" and not description.get("fatal"):
                return Outcome(call_error=description, roundtrip=roundtrip)
            kind = "error"
        else:
            kind = reply.kind
        failure = self._fail(slot, kind, phase, description, timeout)
        return Outcome(failure=failure, roundtrip=roundtrip)
