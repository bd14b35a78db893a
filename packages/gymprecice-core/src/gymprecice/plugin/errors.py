"""The errors gymprecice raises, each meant to be read by a person.

Every message names the file (or solver, or env) at fault and what to do about it. The
hierarchy lets a training loop tell a broken configuration (stop) from a failed solver
(respawn the env and go on).
"""

from __future__ import annotations

from collections.abc import Sequence


class GymPreciceError(Exception):
    """Base class of every error gymprecice raises on purpose."""


class ConfigError(GymPreciceError, ValueError):
    """A configuration file is wrong: the message names the file, the key and the fix."""


class CaseError(GymPreciceError):
    """A solver case directory lacks something the solver needs (mesh, dictionary, patch)."""


class PreciceNotInstalledError(GymPreciceError, ImportError):
    """pyprecice (or the preCICE library behind it) cannot be imported."""


class SolverError(GymPreciceError, RuntimeError):
    """A solver process failed or stopped answering; the episode is over.

    Carries what a person needs to act: the env index, the solver, its exit status and the
    tail of its log. The env can be reset afterwards: nothing of the episode is left running.
    """

    def __init__(
        self,
        message: str,
        *,
        env_index: int | None = None,
        solver: str | None = None,
        returncode: int | None = None,
        log_tail: str = "",
        log_file: str | None = None,
        error_lines: Sequence[str] | None = None,
    ) -> None:
        from gymprecice.plugin.logscan import error_lines as scan
        from gymprecice.plugin.logscan import without_colours

        # A tail is read for a person, in a message or a log file: no colour codes.
        log_tail = without_colours(log_tail)
        self.env_index = env_index
        self.solver = solver
        self.returncode = returncode
        self.log_tail = log_tail
        self.log_file = log_file
        if error_lines is None:  # the solver's own error lines, wherever they are in its log
            error_lines = scan(log_file)
        self.error_lines = tuple(error_lines)
        text = message
        if log_file:
            text += f"\n  log: {log_file}"
        shown = [line for line in self.error_lines if line not in log_tail]
        if shown:
            text += "\n  error lines in the log:\n" + "\n".join("    " + line for line in shown)
        if log_tail:
            tail = "\n".join("    " + line for line in log_tail.rstrip().splitlines())
            text += f"\n  last lines of the log:\n{tail}"
        super().__init__(text)
        self.summary = message

    def __reduce__(self):
        # Keep the error picklable so vector-env workers can send it to the learner.
        return (
            _rebuild_solver_error,
            (
                type(self),
                self.summary,
                self.env_index,
                self.solver,
                self.returncode,
                self.log_tail,
                self.log_file,
                self.error_lines,
            ),
        )


def _rebuild_solver_error(
    cls, summary, env_index, solver, returncode, log_tail, log_file, error_lines=None
):
    return cls(
        summary,
        env_index=env_index,
        solver=solver,
        returncode=returncode,
        log_tail=log_tail,
        log_file=log_file,
        error_lines=error_lines,
    )


class SolverCrashedError(SolverError):
    """A solver process exited (usually with a non-zero status) before the episode ended."""


class SolverDivergedError(SolverError):
    """A solver's own output shows that it diverged: the episode's outcome, not a fault.

    Raised while the solver still runs, when its plugin's
    :func:`~gymprecice.hookspecs.gymprecice_detect_divergence` sees the divergence coming
    (a Courant number past its limit); :class:`~gymprecice.core.Adapter` turns it into a
    terminated step. ``evidence`` is the log line or quantity that showed it.
    """

    def __init__(self, message: str, *, evidence: str = "", **kwargs: object) -> None:
        self.evidence = evidence or message
        super().__init__(message, **kwargs)  # type: ignore[arg-type]


class SolverTimeoutError(SolverError):
    """A solver made no progress within the configured timeout (hung, stopped, deadlocked)."""


class CouplingError(GymPreciceError, RuntimeError):
    """preCICE itself reported an error (bad call order, mesh mismatch, ...)."""
