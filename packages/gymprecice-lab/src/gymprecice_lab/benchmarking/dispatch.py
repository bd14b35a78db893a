"""Where the benchmark's evaluations and sweep run: on a Ray cluster, or here.

With ``--ray`` each evaluation and the baselines' sweep is a Ray task on any node, its
inputs shipped and its output brought back (:mod:`gymprecice_lab.benchmarking.remote_commands`);
without it they run in processes here, ``--workers`` at once. A cluster that is missing,
unreachable or without a node of the CPUs one piece needs is refused before anything
trains (:func:`gymprecice_lab.common.ray_cluster.check_ray`), so the CPUs of one env's
solvers are measured here too.
"""

from __future__ import annotations

import gymnasium as gym

from gymprecice_lab.benchmarking.checks import BenchmarkError
from gymprecice_lab.benchmarking.remote_commands import RemoteCommand
from gymprecice_lab.common.command_runs import run_commands

__all__ = ["run_everywhere", "solver_cpus", "sweep_cpus"]


def solver_cpus(env: gym.Env) -> float:
    """CPUs the solvers of one env use (:attr:`GymPreciceConfig.solver_cpus`; 1 for an env
    without a configuration, such as a test double)."""
    config = getattr(env.unwrapped, "config", None)
    return float(getattr(config, "solver_cpus", 0) or 1)


def sweep_cpus(workers: int, env_cpus: float) -> float:
    """The sweep's ``--workers`` (``workers``) envs at once, on one node."""
    return max(1, workers) * env_cpus


def run_everywhere(
    commands: list[RemoteCommand], ray: str | None, workers: int, one_at_a_time: bool = False
) -> None:
    """Run ``commands`` on the cluster with ``--ray`` (Ray tasks that ship their inputs and
    bring their outputs back) at ``ray`` (``--ray``), else here, ``workers`` at once
    (``one_at_a_time``: a command that spreads its own work over ``--workers``)."""
    if ray:
        from gymprecice_lab.benchmarking.remote_commands import RemoteCommandError
        from gymprecice_lab.benchmarking.remote_commands import run_commands as run_remote_commands

        try:
            run_remote_commands(commands, ray)
        except RemoteCommandError as exc:
            raise BenchmarkError(str(exc), 1) from None
        return
    local = [([*c.argv, *_input_options(c), "--out", str(c.out)], c.what) for c in commands]
    run_commands(local, 1 if one_at_a_time else workers)


def _input_options(command: RemoteCommand) -> list[str]:
    return [item for option, path in command.inputs.items() for item in (option, str(path))]
