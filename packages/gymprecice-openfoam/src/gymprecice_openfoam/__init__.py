"""gymprecice-openfoam: OpenFOAM cases as gymprecice solvers (GPL-3.0, uses foamlib).

Modules: :mod:`.plugin` (hooks), :mod:`.case` (prepare/reset/launch), :mod:`.mesh`
(patch geometry as the OpenFOAM-preCICE adapter sees it), :mod:`.outputs` (incremental
probes/forces readers), :mod:`.actuators` (jets, rotating walls), :mod:`.checks`
(uncoupled-solver detection, doctor), :mod:`.installation` (finding OpenFOAM, running its
programs: :func:`find_openfoam`, :func:`run_tool`, :func:`mpi_env`).
"""

from gymprecice_openfoam.actuators import (
    jet_profile,
    jet_velocity,
    rotating_wall_velocity,
    synthetic_jets,
)
from gymprecice_openfoam.installation import (
    OpenFOAMInstallation,
    find_openfoam,
    mpi_env,
    run_tool,
)
from gymprecice_openfoam.mesh import interface_geometry, patch_geometry, read_precice_dict
from gymprecice_openfoam.outputs import (
    ForceCoeffsReader,
    ForcesReader,
    OutputFormatError,
    OutputTimeoutError,
    ProbesReader,
    Rows,
    read_force_coeffs,
)

__version__ = "0.2.0"

__all__ = [
    "ForceCoeffsReader",
    "ForcesReader",
    "OpenFOAMInstallation",
    "OutputFormatError",
    "OutputTimeoutError",
    "ProbesReader",
    "Rows",
    "find_openfoam",
    "interface_geometry",
    "jet_profile",
    "jet_velocity",
    "mpi_env",
    "patch_geometry",
    "read_force_coeffs",
    "read_precice_dict",
    "rotating_wall_velocity",
    "run_tool",
    "synthetic_jets",
]
