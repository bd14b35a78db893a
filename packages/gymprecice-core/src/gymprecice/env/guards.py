"""What an Adapter's step is checked for: divergence, solver health, finite values.

* **divergence**: a solver pushed past what it can integrate ends the episode with the
  env's penalty, not an error (:mod:`gymprecice.divergence`); each solver's plugin reads
  its log and exit (``gymprecice_detect_divergence``), during a step and after one fails;
* **health**: what is wrong with a solver that waits or exited (the coupling's health
  check): core's own check of the preCICE library first, then the plugin's;
* **finite values**: an observation or reward with NaN or infinity never reaches a
  learner (:func:`~gymprecice.returned_values.refuse_non_finite`).
"""

from __future__ import annotations

import time
from typing import Any

from gymprecice.env.coupled_run import CoupledRun
from gymprecice.env.precice_library import mixed_library_problem
from gymprecice.env.returned_values import refuse_non_finite
from gymprecice.env.solver_process import SolverProcess
from gymprecice.plugin.divergence import HARD_FAULT_STATUSES, Divergence
from gymprecice.plugin.errors import SolverDivergedError, SolverTimeoutError

__all__ = ["Guards", "without_label"]


class Guards:
    """The checks of one env's steps; ``penalty`` is the reward of a diverged step."""

    def __init__(self, run: CoupledRun, penalty: float) -> None:
        self._run = run
        self.penalty = penalty

    # -- finite values ---------------------------------------------------------------------
    def observation(self, value: Any, env_index: int, step: int) -> Any:
        """``value`` from ``_get_observation``, refused if it holds NaN or infinity."""
        refuse_non_finite(value, "_get_observation", env_index, step)
        return value

    def reward(self, value: Any, env_index: int, step: int) -> float:
        """``value`` from ``_get_reward`` as a float, refused if not finite."""
        reward = float(value)
        refuse_non_finite(reward, "_get_reward", env_index, step)
        return reward

    # -- divergence ------------------------------------------------------------------------
    def watch_solver(self, process: SolverProcess) -> str | None:
        """Divergence evidence from a running solver's log (the coupling's ``watch``)."""
        ctx = self._run.solvers.get(process.name)
        if ctx is None:
            return None
        return self._run.hook.gymprecice_detect_divergence(
            solver=ctx, log_text=process.log_tail(200), returncode=None
        )

    def watch_all(self, session: Any, now: float) -> Divergence | None:
        """The first running solver whose log shows divergence, at simulated time ``now``."""
        for process in session.solvers:
            if process.poll() is None:
                evidence = self.watch_solver(process)
                if evidence:
                    return Divergence(process.name, now, evidence)
        return None

    def confirm_divergence(
        self, session: Any, now: float, patience: float = 5.0
    ) -> Divergence | None:
        """Watch the solvers' logs for up to ``patience`` s (bounded by the progress timeout)."""
        deadline = time.monotonic() + min(patience, self._run.timeouts.progress)
        while True:
            evidence = self.watch_all(session, now)
            if evidence is not None or time.monotonic() >= deadline:
                return evidence
            time.sleep(0.2)

    def divergence(self, exc: Exception, session: Any, now: float) -> Divergence | None:
        """Whether a failed step is the solver's divergence rather than a fault.

        A hang stays a fault, and so does a culprit killed from outside or crashed by
        its binary (:data:`~gymprecice.divergence.HARD_FAULT_STATUSES`). Otherwise each
        solver's plugin classifies its exit and log, the failing solver first.
        """
        if isinstance(exc, SolverDivergedError):
            return Divergence(exc.solver or "solver", now, exc.evidence)
        if isinstance(exc, SolverTimeoutError) or session is None:
            return None
        culprit = getattr(exc, "solver", None)
        processes = sorted(session.solvers, key=lambda p: p.name != culprit)
        for process in processes:
            status = process.poll()
            if process.name == culprit and status in HARD_FAULT_STATUSES:
                return None
            ctx = self._run.solvers.get(process.name)
            if ctx is None or status is None:
                continue
            evidence = self._run.hook.gymprecice_detect_divergence(
                solver=ctx, log_text=process.log_tail(200), returncode=status
            )
            if evidence:
                return Divergence(process.name, now, evidence)
        return None

    # -- health ----------------------------------------------------------------------------
    def health_check(self, process: SolverProcess) -> str | None:
        """What is wrong with a waiting or exited solver: core's own check, then the plugin's.

        Core checks that the solver runs the env's preCICE library (a mixed set-up waits
        forever); the plugin's diagnosis comes without the solver's name.

        Core's error message names the solver and the env already; a plugin that starts
        its message with ``solver.describe()`` (as the hook spec once showed) would have
        it twice.
        """
        ctx = self._run.solvers.get(process.name)
        if ctx is None:
            return None
        log_text = process.log_tail(200)
        mixed = mixed_library_problem(ctx.precice_library, log_text)
        if mixed:
            return mixed
        problem = self._run.hook.gymprecice_check_solver(solver=ctx, log_text=log_text)
        return without_label(problem, ctx.describe()) if problem else None


def without_label(message: str, label: str) -> str:
    """``message`` without a leading ``label`` (and the colon after it)."""
    if message.startswith(label):
        return message[len(label) :].lstrip(" :") or message
    return message
