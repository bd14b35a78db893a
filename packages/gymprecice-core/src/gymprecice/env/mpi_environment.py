"""A solver's environment without the MPI runtime variables of an enclosing MPI job.

Solver scripts often call ``mpirun``. That breaks when the Python process initialised an
MPI singleton (``from mpi4py import MPI``) before its environment reached the solver, or
runs inside an MPI job itself: a child ``mpirun`` that sees the launcher's variables
believes it is one of the job's ranks and refuses to start. :func:`clean_mpi_environment`
removes those runtime variables and keeps the user's MPI configuration.
"""

from __future__ import annotations

from collections.abc import Mapping

__all__ = ["clean_mpi_environment"]

# Variables a launcher (mpirun/orted/prterun, Hydra, srun's PMI) or an Open MPI singleton
# sets for the processes it starts. A child ``mpirun`` that sees them believes it runs
# inside an MPI job and stops ("mpirun does not support recursive calls", or a silent
# exit status 1 with OMPI_MCA_ess=singleton on Open MPI 4.1).
_RUNTIME_EXACT = frozenset(
    {
        # Open MPI 4 (ORTE) singleton and launcher
        "OMPI_MCA_ess",
        "OMPI_MCA_pmix",
        "OMPI_MCA_initial_wdir",
        "OMPI_MCA_mpi_oversubscribe",
        "OMPI_MCA_shmem_RUNTIME_QUERY_hint",
        "OMPI_UNIVERSE_SIZE",
        "OMPI_FILE_LOCATION",
        "OMPI_NUM_APP_CTX",
        "OMPI_FIRST_RANKS",
        "OMPI_COMMAND",
        "OMPI_ARGV",
        # MPICH / Intel MPI (Hydra) per-rank information
        "MPI_LOCALRANKID",
        "MPI_LOCALNRANKS",
    }
)
_RUNTIME_PREFIXES = (
    "OMPI_COMM_WORLD_",
    "OMPI_APP_CTX_",
    "OMPI_MCA_ess_",
    "OMPI_MCA_orte_",
    "OMPI_MCA_pmix_",
    "ORTE_",
    "PMIX_",
    "PRTE_",
    "PMI_",
    "HYDI_",
)
# User configuration that matches a runtime prefix above but must survive.
_USER_PREFIXES = ("PMIX_MCA_", "PRTE_MCA_")
_USER_EXACT = frozenset(
    {
        "OMPI_MCA_orte_tmpdir_base",
        "OMPI_MCA_orte_default_hostfile",
        "OMPI_MCA_orte_keep_fqdn_hostnames",
        "OMPI_MCA_orte_base_help_aggregate",
        "OMPI_MCA_orte_abort_on_non_zero_status",
        "OMPI_MCA_orte_allowed_exit_without_sync",
    }
)


def _is_mpi_runtime_variable(name: str) -> bool:
    if name in _USER_EXACT or name.startswith(_USER_PREFIXES):
        return False
    return name in _RUNTIME_EXACT or name.startswith(_RUNTIME_PREFIXES)


def clean_mpi_environment(environ: Mapping[str, str]) -> dict[str, str]:
    """Return a copy of ``environ`` without the MPI runtime variables of an enclosing job.

    Gym-preCICE v0.1 dropped every variable containing ``MPI``, which also dropped the
    user's ``OMPI_ALLOW_RUN_AS_ROOT*`` and MCA settings (``OMPI_MCA_btl*``,
    ``OMPI_MCA_rmaps_base_oversubscribe``, ``I_MPI_*``, ``MPIR_CVAR_*``, ...) and so broke
    runs as root and tuned clusters. Only what a launcher or a singleton sets is removed
    here: ``OMPI_COMM_WORLD_*``, ``OMPI_MCA_ess*``, ``OMPI_MCA_orte_*`` (except a few
    documented user settings such as ``OMPI_MCA_orte_tmpdir_base``), ``OMPI_MCA_pmix*``,
    ``PMIX_*`` and ``PRTE_*`` (except ``PMIX_MCA_*`` / ``PRTE_MCA_*``), ``PMI_*``,
    ``ORTE_*``, ``OMPI_APP_CTX_*``, ``OMPI_UNIVERSE_SIZE``, ``OMPI_FILE_LOCATION``,
    ``MPI_LOCALRANKID`` and similar. ``HYDRA_*`` variables are kept: Hydra reads them as
    user settings (``HYDRA_HOST_FILE``, ``HYDRA_LAUNCHER``).

    Note that an MPI singleton sets its variables with ``putenv``, which Python's
    ``os.environ`` does not see in the process that imported mpi4py; they reach
    ``os.environ`` of every process started from it (vector-env workers, the coupling
    worker), and from there the solvers unless they are removed.
    """
    return {k: v for k, v in environ.items() if not _is_mpi_runtime_variable(k)}
