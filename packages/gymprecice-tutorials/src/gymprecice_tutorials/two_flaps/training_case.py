"""The two flaps' training case as files: the packaged case with measured edits.

One module owns what the training case *is* (its edits, its time window, its action
length), so that the environment (:mod:`.fast`) and the test double's case (:mod:`.double`)
both build on it without importing each other. Why each edit: :mod:`.fast`'s docstring.
"""

from __future__ import annotations

import re

from gymprecice_tutorials.case_files import apply_edits
from gymprecice_tutorials.two_flaps import CASE_DIR

__all__ = [
    "ACTION_TIME",
    "FAST_EDITS",
    "WINDOW",
    "case_files",
    "fast_case_files",
    "packaged_case_files",
]

_SOLIDS = ("solid-upstream-dealii/parameters.prm", "solid-downstream-dealii/parameters.prm")
_MESH = "fluid-openfoam/system/blockMeshDict"

#: (file, old text, new text): the training case is the packaged case with these edits.
#: Each old text must occur exactly once, so a change of the packaged case that would
#: silently drop an edit fails instead.
FAST_EDITS: tuple[tuple[str, str, str], ...] = (
    # half the cells in each direction: 1,208 cells instead of 4,650
    (_MESH, "nxIn        14;", "nxIn        7;"),
    (_MESH, "nxJet       3;", "nxJet       2;"),
    (_MESH, "nxGap       3;", "nxGap       2;"),
    (_MESH, "nxFlap      4;", "nxFlap      2;"),
    (_MESH, "nxMid       20;", "nxMid       10;"),
    (_MESH, "nxOut       20;", "nxOut       10;"),
    (_MESH, "nyFlap      20;", "nyFlap      10;"),
    (_MESH, "nyAbove     45;", "nyAbove     22;"),
    # the fluid's time step: 2 per preCICE window of 0.05 s
    ("fluid-openfoam/system/controlDict", "deltaT          0.01;", "deltaT          0.025;"),
    # the solids: one step per window, elements of degree 2
    *(
        edit
        for prm in _SOLIDS
        for edit in (
            (prm, "set Time step size  = 0.01", "set Time step size  = 0.05"),
            (prm, "set Polynomial degree = 4", "set Polynomial degree = 2"),
        )
    ),
    # two windows per action (0.1 s, as the packaged case's ten)
    ("gymprecice-config.json", '"windows": 10', '"windows": 2'),
)
#: the looser coupling: the multi scheme's relative convergence limit (published: 1e-4)
FAST_CONVERGENCE_LIMIT = "1e-3"
#: the training case's preCICE time window (s)
WINDOW = 0.05
#: simulated seconds per action (two windows)
ACTION_TIME = 0.1


def case_files() -> dict[str, str]:
    """The packaged case's files, relative path -> text."""
    return {
        str(path.relative_to(CASE_DIR)): path.read_text()
        for path in sorted(CASE_DIR.rglob("*"))
        if path.is_file()
    }


def packaged_case_files(end_time: float) -> dict[str, str]:
    """The packaged case's files with the run's end (preCICE max-time, the solvers' end
    times) at ``end_time``: the published setup run for as long as a comparison needs."""
    return _edited(case_files(), [], end_time, limit="1e-4", window=0.01)


def fast_case_files(end_time: float) -> dict[str, str]:
    """The training case's files: the packaged case with :data:`FAST_EDITS`, the looser
    coupling and the run's end (preCICE max-time, the solvers' end times) at ``end_time``."""
    return _edited(case_files(), FAST_EDITS, end_time, limit=FAST_CONVERGENCE_LIMIT, window=WINDOW)


def _edited(
    files: dict[str, str],
    edits: tuple[tuple[str, str, str], ...] | list,
    end_time: float,
    *,
    limit: str,
    window: float,
) -> dict[str, str]:
    edits = [
        *edits,
        *(
            (prm, "set End time        = 5", f"set End time        = {_fmt(end_time + 1)}")
            for prm in _SOLIDS
        ),
        (
            "fluid-openfoam/system/controlDict",
            "endTime         5;",
            f"endTime         {_fmt(end_time + 1)};",
        ),
    ]
    apply_edits(files, edits, CASE_DIR, "gymprecice_tutorials.two_flaps.training_case")
    xml = "precice-config.xml"
    text = files[xml]
    text, schemes = re.subn(
        r'<max-time value="[^"]*" />', f'<max-time value="{_fmt(end_time)}" />', text
    )
    text, windows = re.subn(
        r'<time-window-size value="0.01" />', f'<time-window-size value="{_fmt(window)}" />', text
    )
    text, limits = re.subn(
        r'relative-convergence-measure limit="1e-4"',
        f'relative-convergence-measure limit="{limit}"',
        text,
    )
    if (schemes, windows, limits) != (2, 2, 4):
        raise ValueError(
            f"{CASE_DIR / xml}: expected 2 coupling schemes' max-time and time window and 4 "
            f"convergence measures of limit 1e-4, found {schemes}, {windows} and {limits}; "
            "update gymprecice_tutorials.two_flaps.training_case to the packaged case"
        )
    files[xml] = text
    return files


def _fmt(value: float) -> str:
    return f"{value:.10g}"
