"""Running a short command of a solver (its prerun, its reset) to its end, with a deadline.

A plugin's prerun or reset command runs like a solver, in a process group of its own with
its output in a log, and is waited for: a non-zero exit and a command that runs past its
deadline are errors that name the command and carry its log's tail. The group is killed
when the command ends, so nothing it left in the background outlives it.
"""

from __future__ import annotations

from gymprecice.env.exit_status import describe_returncode
from gymprecice.env.pidregistry import PidRegistry
from gymprecice.env.solver_process import SolverProcess
from gymprecice.plugin.errors import SolverCrashedError, SolverTimeoutError
from gymprecice.plugin.solver import LaunchSpec

__all__ = ["run_to_completion"]


def run_to_completion(
    name: str,
    spec: LaunchSpec,
    *,
    timeout: float | None,
    env_index: int = 0,
    what: str = "prerun",
    registry: PidRegistry | None = None,
    append: bool = False,
) -> None:
    """Run a short command (prerun, reset) in its own group and wait for it.

    Raises :class:`~gymprecice.errors.SolverCrashedError` on a non-zero exit and
    :class:`~gymprecice.errors.SolverTimeoutError` (after killing the group) when it runs
    longer than ``timeout`` seconds. Processes the command left in the background are
    killed too: nothing it started outlives it.
    """
    proc = SolverProcess.start(name, spec, env_index=env_index, registry=registry, append=append)
    try:
        returncode = proc.wait(timeout)
        if returncode is None:
            proc.terminate()
            raise SolverTimeoutError(
                f"the {what} command of solver {name!r} (env {env_index}) did not finish "
                f"within {timeout:g} s and was killed: {proc.command}",
                env_index=env_index,
                solver=name,
                returncode=proc.returncode,
                log_tail=proc.log_tail(),
                log_file=str(proc.log_path),
            )
        if returncode != 0:
            proc.terminate()
            raise SolverCrashedError(
                f"the {what} command of solver {name!r} (env {env_index}) "
                f"{describe_returncode(returncode)}: {proc.command}",
                env_index=env_index,
                solver=name,
                returncode=returncode,
                log_tail=proc.log_tail(),
                log_file=str(proc.log_path),
            )
    finally:
        proc.terminate()
