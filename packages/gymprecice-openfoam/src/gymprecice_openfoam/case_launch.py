"""Describe the coupled run of a prepared case: the command, its environment and its log.

What core starts each episode (``<app>`` or ``mpirun -np N <app> -parallel``), with the
OpenFOAM environment and the adapter the plugin installed. It only reads the prepared
state, so it is apart from preparing and resetting the case.
"""

from __future__ import annotations

import os
from pathlib import Path

from gymprecice.plugin import CaseError, LaunchSpec, SolverContext, solver_environment
from gymprecice_openfoam.case_state import prepared_state
from gymprecice_openfoam.installation import find_openfoam, mpi_env


def launch_spec(solver: SolverContext) -> LaunchSpec:
    """The coupled run: ``<app>`` or ``mpirun -np N <app> -parallel`` in the run dir."""
    run_dir = Path(solver.run_dir)
    state = prepared_state(solver)
    inst = find_openfoam(bashrc=solver.options.get("openfoam_bashrc"))
    program = inst.which(state.application)
    if program is None:
        raise CaseError(
            f"{state.application}: not found in the OpenFOAM installation at {inst.project_dir}"
        )
    extra = [str(a) for a in solver.options.get("solver_args", [])]
    env = dict(inst.env)
    # the adapter built by `gymprecice install` (OpenFOAM dlopens it by bare name)
    env.update(solver_environment({**os.environ, **env}))
    if state.np > 1:
        mpirun = inst.which("mpirun")
        if mpirun is None:
            raise CaseError(
                f"{solver.describe()}: the case runs on {state.np} processes but mpirun is "
                "not on PATH; install MPI or set np=1"
            )
        mpi_args = [str(a) for a in solver.options.get("mpirun_args", [])]
        argv = [mpirun, "-np", str(state.np), *mpi_args, program, "-parallel", *extra]
        env.update(mpi_env())
    else:
        argv = [program, *extra]
    return LaunchSpec(argv=argv, cwd=run_dir, env=env, log_name=log_name(state.application))


def log_name(application: str) -> str:
    """Name of the episode's solver log in the run directory."""
    return f"log.{application}"
