"""Parametric recipes for the OpenFOAM tutorial cases.

Every file of the packaged cases under ``gymprecice_tutorials/cases/`` is written by this
package; the committed copies are its output for the default parameters (a test checks that
they agree). A case directory holds::

    <case>/gymprecice-config.json     explicit form (solver "fluid", kind "openfoam")
    <case>/precice-config.xml         preCICE v3: Controller <-> Fluid, parallel-explicit
    <case>/fluid-openfoam/            OpenFOAM case (pimpleFoam), no mesh, no snapshot
        0/U 0/p
        constant/transportProperties constant/turbulenceProperties constant/momentumTransport
        system/blockMeshDict system/controlDict system/fvSchemes system/fvSolution
        system/decomposeParDict system/preciceDict
        system/probes system/forceCoeffs          function objects, included by controlDict
        system/preciceAdapterFunctionObject       the preCICE adapter, included by controlDict

The flow is the Schäfer-Turek 2D-2 benchmark (channel 2.2 x 0.41, cylinder D = 0.1 at
(0.2, 0.2), parabolic inflow with Umax = 1.5, nu = 1e-3, Re = Umean D / nu = 100).

One room per idea; this module only gathers their public names:

* :mod:`~gymprecice_tutorials.recipes.spec`: the parameters (:class:`CaseSpec`,
  :class:`Geometry`, :class:`Resolution`, :class:`Flow`) and the packaged :data:`CASES`;
* :mod:`~gymprecice_tutorials.recipes.mesh`: block cell counts and ``blockMeshDict``;
* :mod:`~gymprecice_tutorials.recipes.probes`: where the observation's probes sit;
* :mod:`~gymprecice_tutorials.recipes.foam_files`: the flow's other OpenFOAM dictionaries;
* :mod:`~gymprecice_tutorials.recipes.coupling`: ``precice-config.xml``,
  ``gymprecice-config.json`` and the OpenFOAM-preCICE adapter's files;
* :mod:`~gymprecice_tutorials.recipes.foam_format`: how a dictionary is written;
* :mod:`~gymprecice_tutorials.recipes.case`: a whole case written to disk, made uncoupled
  (pre-runs, validation: :func:`make_uncoupled` empties
  ``system/preciceAdapterFunctionObject``, which controlDict includes with a plain
  ``#include``, so a coupled run never starts without the adapter), the packaged cases
  regenerated;
* :mod:`~gymprecice_tutorials.recipes.cli`: the command line.

Command line::

    python -m gymprecice_tutorials.recipes write jet_cylinder DIR [--cells-per-jet N ...]
    python -m gymprecice_tutorials.recipes regenerate     # rewrite the packaged cases
    python -m gymprecice_tutorials.recipes info [NAME]    # block counts and cell estimate
"""

from gymprecice_tutorials.recipes.case import (
    case_files,
    fluid_files,
    make_coupled,
    make_uncoupled,
    regenerate,
    write_case,
    write_fluid_case,
)
from gymprecice_tutorials.recipes.cli import add_resolution_options, main, resolution_overrides
from gymprecice_tutorials.recipes.coupling import gymprecice_config, mesh_name, precice_config
from gymprecice_tutorials.recipes.mesh import BlockCounts, block_counts, blockmesh_dict
from gymprecice_tutorials.recipes.probes import probe_locations
from gymprecice_tutorials.recipes.spec import (
    CASES,
    CASES_DIR,
    FAST_TRAINING,
    FLUID_DIR,
    PRECICE_FO_FILE,
    CaseSpec,
    Control,
    Coupling,
    Flow,
    Geometry,
    Resolution,
    case_spec,
)

__all__ = [
    "CASES",
    "CASES_DIR",
    "FAST_TRAINING",
    "FLUID_DIR",
    "PRECICE_FO_FILE",
    "BlockCounts",
    "CaseSpec",
    "Control",
    "Coupling",
    "Flow",
    "Geometry",
    "Resolution",
    "add_resolution_options",
    "block_counts",
    "blockmesh_dict",
    "case_files",
    "case_spec",
    "fluid_files",
    "gymprecice_config",
    "main",
    "make_coupled",
    "make_uncoupled",
    "mesh_name",
    "precice_config",
    "probe_locations",
    "regenerate",
    "resolution_overrides",
    "write_case",
    "write_fluid_case",
]
