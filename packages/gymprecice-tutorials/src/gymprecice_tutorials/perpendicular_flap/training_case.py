"""The flap's training case as files: the packaged case with measured edits.

One module owns what the training case *is* (its edits, its time window, its action
length), so that the environment (:mod:`.fast`) and the test double's case
(:mod:`.double`) both build on it without importing each other. The reasons for each
edit are in :mod:`.fast`'s docstring and docs/training.md, "The flap".
"""

from __future__ import annotations

import re

from gymprecice_tutorials.case_files import apply_edits
from gymprecice_tutorials.perpendicular_flap import CASE_DIR
from gymprecice_tutorials.perpendicular_flap.packaged_case import SOLIDS, case_files

__all__ = [
    "ACTION_TIME",
    "FAST_EDITS",
    "PRECICE_OBSERVATION_EDITS",
    "TIP",
    "WINDOW",
    "fast_case_files",
]

#: (file, old text, new text): the training case is the packaged case with these edits.
#: Each old text must occur exactly once, so a change of the packaged case that would
#: silently drop an edit fails instead.
FAST_EDITS: tuple[tuple[str, str, str], ...] = (
    ("fluid-openfoam/system/blockMeshDict", "nxSide      30;", "nxSide      15;"),
    ("fluid-openfoam/system/blockMeshDict", "nxFlap      4;", "nxFlap      2;"),
    ("fluid-openfoam/system/blockMeshDict", "nyFlap      15;", "nyFlap      8;"),
    ("fluid-openfoam/system/blockMeshDict", "nyAbove     45;", "nyAbove     22;"),
    ("fluid-openfoam/system/controlDict", "deltaT          0.01;", "deltaT          0.025;"),
    ("solid-dealii/parameters.prm", "set Time step size  = 0.01", "set Time step size  = 0.05"),
    ("solid-dealii/parameters.prm", "set Polynomial degree = 4", "set Polynomial degree = 2"),
    # the FEniCS solid copies the deal.II solid's coupling vertices, of degree 2 here
    ("solid-fenics/solid.py", "DEALII_DEGREE = 4", "DEALII_DEGREE = 2"),
    ("gymprecice-config.json", '"windows": 10', '"windows": 2'),
)
#: (file, old text, new text) that give the controller the tip's state through preCICE
#: (``observe="precice"``): two one-vertex controller meshes at the tip, the solid's
#: displacement mapped onto one and the fluid's force onto the other (preCICE maps one
#: data name onto a mesh from one mesh only, and the solid's mesh carries a force too),
#: each sent in an explicit scheme that preCICE runs after the implicit fluid-solid scheme
#: of the window has converged.
PRECICE_OBSERVATION_EDITS: tuple[tuple[str, str, str], ...] = (
    (
        "precice-config.xml",
        '  <mesh name="Controller-Mesh-inlet" dimensions="2">',
        '  <mesh name="Controller-Mesh-tip" dimensions="2">\n'
        '    <use-data name="Displacement" />\n'
        "  </mesh>\n\n"
        '  <mesh name="Controller-Mesh-force" dimensions="2">\n'
        '    <use-data name="Force" />\n'
        "  </mesh>\n\n"
        '  <mesh name="Controller-Mesh-inlet" dimensions="2">',
    ),
    (
        "precice-config.xml",
        '    <write-data name="Velocity" mesh="Controller-Mesh-inlet" />\n',
        '    <write-data name="Velocity" mesh="Controller-Mesh-inlet" />\n'
        '    <provide-mesh name="Controller-Mesh-tip" />\n'
        '    <provide-mesh name="Controller-Mesh-force" />\n'
        '    <receive-mesh name="Solid-Mesh" from="Solid" />\n'
        '    <receive-mesh name="Fluid-Mesh-flap" from="Fluid" />\n'
        '    <read-data name="Displacement" mesh="Controller-Mesh-tip" />\n'
        '    <read-data name="Force" mesh="Controller-Mesh-force" />\n'
        '    <mapping:nearest-neighbor direction="read" from="Solid-Mesh" '
        'to="Controller-Mesh-tip" constraint="consistent" />\n'
        '    <mapping:nearest-neighbor direction="read" from="Fluid-Mesh-flap" '
        'to="Controller-Mesh-force" constraint="consistent" />\n',
    ),
    (
        "precice-config.xml",
        '  <m2n:sockets acceptor="Fluid" connector="Controller" exchange-directory=".." />\n',
        '  <m2n:sockets acceptor="Fluid" connector="Controller" exchange-directory=".." />\n'
        '  <m2n:sockets acceptor="Solid" connector="Controller" exchange-directory=".." />\n',
    ),
    (
        "precice-config.xml",
        '    <exchange data="Velocity" mesh="Controller-Mesh-inlet" from="Controller" '
        'to="Fluid" initialize="true" />\n'
        "  </coupling-scheme:parallel-explicit>\n",
        '    <exchange data="Velocity" mesh="Controller-Mesh-inlet" from="Controller" '
        'to="Fluid" initialize="true" />\n'
        '    <exchange data="Force" mesh="Fluid-Mesh-flap" from="Fluid" to="Controller" />\n'
        "  </coupling-scheme:parallel-explicit>\n\n"
        "  <!-- the tip's displacement, once the window's fluid-solid iterations converged -->\n"
        "  <coupling-scheme:parallel-explicit>\n"
        '    <participants first="Controller" second="Solid" />\n'
        '    <max-time value="5.0" />\n'
        '    <time-window-size value="0.01" />\n'
        '    <exchange data="Displacement" mesh="Solid-Mesh" from="Solid" to="Controller" />\n'
        "  </coupling-scheme:parallel-explicit>\n",
    ),
    (
        "gymprecice-config.json",
        '"write_to": {"inlet": "Velocity"}',
        '"write_to": {"inlet": "Velocity"},\n        "read_from": {"tip": "Displacement", "force": "Force"}',
    ),
)
#: the flap tip, where both observation routes look (m)
TIP = (0.0, 1.0)
#: the training case's preCICE time window (s)
WINDOW = 0.05
#: simulated seconds per action (two windows)
ACTION_TIME = 0.1


def fast_case_files(
    end_time: float, observe: str = "watchpoint", solid: str = "dealii"
) -> dict[str, str]:
    """The training case's files: the packaged case with the solid ``solid``
    (:mod:`.packaged_case`), :data:`FAST_EDITS` applied and the run's end (preCICE
    max-time, the solvers' end times) at ``end_time``; with ``observe="precice"``,
    :data:`PRECICE_OBSERVATION_EDITS` too.

    The edits of a solid's directory apply to that solid only. The FEniCS solid takes its
    time step from preCICE's window and runs until the coupling ends; its edit makes its
    coupling vertices those of the deal.II solid of degree 2.
    """
    files = case_files(solid)
    edits = [
        *FAST_EDITS,
        *(PRECICE_OBSERVATION_EDITS if observe == "precice" else ()),
        (
            "solid-dealii/parameters.prm",
            "set End time        = 5",
            f"set End time        = {_fmt(end_time + 1)}",
        ),
        (
            "fluid-openfoam/system/controlDict",
            "endTime         5;",
            f"endTime         {_fmt(end_time + 1)};",
        ),
    ]
    other = {directory for name, directory in SOLIDS.items() if name != solid}
    edits = [edit for edit in edits if edit[0].split("/", 1)[0] not in other]
    apply_edits(files, edits, CASE_DIR, "gymprecice_tutorials.perpendicular_flap.training_case")
    xml = "precice-config.xml"
    files[xml], count = re.subn(
        r'<max-time value="[^"]*" />', f'<max-time value="{_fmt(end_time)}" />', files[xml]
    )
    schemes = 3 if observe == "precice" else 2
    if count != schemes:
        raise ValueError(
            f"{CASE_DIR / xml}: expected {schemes} coupling schemes' max-time, found {count}"
        )
    files[xml] = files[xml].replace(
        'time-window-size value="0.01"', f'time-window-size value="{_fmt(WINDOW)}"'
    )
    return files


def _fmt(value: float) -> str:
    return f"{value:.10g}"
