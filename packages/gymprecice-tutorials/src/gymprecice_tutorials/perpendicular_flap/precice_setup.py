"""preCICE's own perpendicular flap: the packaged case as preCICE's tutorial sets it up.

The flap's environments change preCICE's tutorial in one way that matters: the inflow is a
parabolic jet the controller moves. To validate the coupled simulation under them against
preCICE's published results, ``PerpendicularFlapEnv(setup="precice")`` runs the tutorial's
own setup through the same machinery (the same three participants, the same solids, the
controller writing the inlet velocity every time window):

* the channel (6 x 4), the flap (0.1 x 1), the fluid (density 1, nu 1 m²/s) and the solid
  (3000 kg/m³, E 4 MPa, nu 0.3, deal.II degree 4 or the FEniCS flap) are the packaged
  case's already;
* the fluid mesh is the tutorial's (:data:`PRECICE_SETUP_EDITS`): 30 cells up- and
  downstream of the flap, 3 across it, 15 along it and 30 above it, graded as the
  tutorial grades them (2,790 cells, against the packaged case's 3,780);
* the fluid starts at 10 m/s everywhere, as the tutorial's initial field does, and the
  inflow is uniform: every inlet face gets the action's speed, 10 m/s in the reference;
* the PIMPLE loop makes 4 pressure corrections, as the tutorial's.

What stays the packaged case's: the controller's explicit coupling to the fluid (it only
writes the inlet, once per window), the fluid-solid implicit scheme with its IQN-ILS
acceleration and 5e-3 convergence limits (the tutorial's), and the 0.01 s time window.
"""

from __future__ import annotations

from gymprecice_tutorials.case_files import apply_edits
from gymprecice_tutorials.perpendicular_flap import CASE_DIR
from gymprecice_tutorials.perpendicular_flap.packaged_case import SOLIDS, case_files

__all__ = ["PRECICE_SETUP_EDITS", "SETUPS", "setup_case_files"]

#: what ``PerpendicularFlapEnv(setup=...)`` runs: the steerable jet, or preCICE's tutorial
SETUPS = ("jet", "precice")

_MESH = "fluid-openfoam/system/blockMeshDict"
#: (file, old text, new text): preCICE's setup is the packaged case with these edits, each
#: matching exactly once (a changed packaged case fails loudly instead of half edited)
PRECICE_SETUP_EDITS: tuple[tuple[str, str, str], ...] = (
    (_MESH, "nxFlap      4;", "nxFlap      3;"),
    (_MESH, "nyAbove     45;", "nyAbove     30;"),
    (_MESH, "gradeIn     0.4;", "gradeIn     0.5;"),
    (_MESH, "gradeOut    2.5;", "gradeOut    2;"),
    # the tutorial grades the cells above the tip 2 : 1 towards the upper wall
    (
        _MESH,
        "hex (4 5 9 8 16 17 21 20) ($nxSide $nyAbove 1) simpleGrading ($gradeIn 1 1)",
        "hex (4 5 9 8 16 17 21 20) ($nxSide $nyAbove 1) simpleGrading ($gradeIn 2 1)",
    ),
    (
        _MESH,
        "hex (5 6 10 9 17 18 22 21) ($nxFlap $nyAbove 1) simpleGrading (1 1 1)",
        "hex (5 6 10 9 17 18 22 21) ($nxFlap $nyAbove 1) simpleGrading (1 2 1)",
    ),
    (
        _MESH,
        "hex (6 7 11 10 18 19 23 22) ($nxSide $nyAbove 1) simpleGrading ($gradeOut 1 1)",
        "hex (6 7 11 10 18 19 23 22) ($nxSide $nyAbove 1) simpleGrading ($gradeOut 2 1)",
    ),
    (
        "fluid-openfoam/system/fvSolution",
        "nCorrectors              3;",
        "nCorrectors              4;",
    ),
)


def setup_case_files(solid: str = "dealii", speed: float = 10.0) -> dict[str, str]:
    """The files of preCICE's setup with ``solid``, its fluid starting at ``speed`` m/s."""
    files = case_files(solid)
    edits = [
        *PRECICE_SETUP_EDITS,
        (
            "fluid-openfoam/0/U",
            "// The fluid starts at rest; the controller's first action sets the inlet at t = 0.\n"
            "internalField   uniform (0 0 0);",
            "// preCICE's tutorial: the fluid starts at the inflow's speed.\n"
            f"internalField   uniform ({speed:.10g} 0 0);",
        ),
    ]
    other = {directory for name, directory in SOLIDS.items() if name != solid}
    edits = [edit for edit in edits if edit[0].split("/", 1)[0] not in other]
    apply_edits(
        files,
        edits,
        CASE_DIR,
        "gymprecice_tutorials.perpendicular_flap.precice_setup",
        "PRECICE_SETUP_EDITS",
    )
    return files
