"""gymprecice-openfoam: OpenFOAM cases as gymprecice solvers (GPL-3.0, uses foamlib).

Modules: :mod:`.plugin` (hooks), :mod:`.case` (prepare/reset/launch), :mod:`.mesh`
(patch geometry as the OpenFOAM-preCICE adapter sees it), :mod:`.outputs` (incremental
probes/forces readers), :mod:`.actuators` (jets, rotating walls), :mod:`.checks`
(uncoupled-solver detection, doctor), :mod:`.installation` (finding OpenFOAM).
"""

from gymprecice_openfoam.actuators import (
    jet_profile,
    jet_velocity,
    rotating_wall_velocity,
    synthetic_jets,
)
from gymprecice_openfoam.installation import OpenFOAMInstallation, find_openfoam
from gymprecice_openfoam.mesh import interface_geometry, patch_geometry, read_precice_dict
from gymprecice_openfoam.outputs import (
    ForceCoeffsReader,
    ForcesReader,
    OutputFormatError,
    OutputTimeoutError,
    ProbesReader,
    Rows,
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
    "patch_geometry",
    "read_precice_dict",
    "rotating_wall_velocity",
    "synthetic_jets",
]
