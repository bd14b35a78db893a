"""Starting solver processes and ending them: process groups, logs, exit notification.

Plugins only describe how a solver starts (:class:`~gymprecice.solver.LaunchSpec`); core
starts it. Every solver runs in its own session and process group, so one signal to the
group reaches everything the solver started (``mpirun``, its ranks, a shell script's
background jobs) and nothing else. Each group is recorded on disk before it exists
(:mod:`gymprecice.pidregistry`), so an outer supervisor can still kill it after the env
process itself died, and every kill proves the identity of what it signals first.

No solver outlives the process that owns its env, whatever kills that process (``kill -9``,
the OOM killer, a job's time limit): the kernel kills each child when its parent dies
(``PR_SET_PDEATHSIG``), and the owner's watchdog (:mod:`gymprecice.owner_watchdog`) kills
the rest of the group and of its session once the owner is gone.

This module is the one place that names all of it; each part lives in a module of its own:

* :mod:`gymprecice.env.solver_process`: :class:`SolverProcess`, one running solver (its
  group, its log, the descriptor that wakes a waiter when it exits, its end);
* :mod:`gymprecice.env.launching`: :func:`launch`, a child in a new session and process
  group, recorded before it exists (:class:`Launched`);
* :mod:`gymprecice.env.parent_death`: children that die with this process
  (``PR_SET_PDEATHSIG``, :func:`call_in_lasting_thread`);
* :mod:`gymprecice.env.short_commands`: :func:`run_to_completion`, a prerun or reset
  command waited for with a deadline;
* :mod:`gymprecice.env.solver_log`: the log file and its tail (:func:`read_tail`);
* :mod:`gymprecice.env.mpi_environment`: :func:`clean_mpi_environment`, so that a
  solver's ``mpirun`` starts from a Python process that initialised MPI;
* :mod:`gymprecice.env.exit_status`: :func:`describe_returncode`, an exit status in words.

Every name this module had before the split is still importable from it (and from its
old path, ``gymprecice.processes``); new code imports from the module that owns the name.
"""

from __future__ import annotations

from gymprecice.env.exit_status import describe_returncode
from gymprecice.env.launching import Launched, launch
from gymprecice.env.mpi_environment import clean_mpi_environment
from gymprecice.env.parent_death import call_in_lasting_thread
from gymprecice.env.pidregistry import (
    PROCESS_TOKEN_VARIABLE,
    GroupRecord,
    PidRegistry,
    kill_recorded_groups,
)
from gymprecice.env.short_commands import run_to_completion
from gymprecice.env.solver_log import read_tail
from gymprecice.env.solver_process import SolverProcess

__all__ = [
    "PROCESS_TOKEN_VARIABLE",
    "GroupRecord",
    "Launched",
    "PidRegistry",
    "SolverProcess",
    "call_in_lasting_thread",
    "clean_mpi_environment",
    "describe_returncode",
    "kill_recorded_groups",
    "launch",
    "read_tail",
    "run_to_completion",
]
