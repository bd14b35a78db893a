"""The FSI3 case's files for one run: the packaged files, the mesh, the inflow, the times.

``case/`` holds what does not change from run to run. :func:`case_files` adds the fluid
mesh of a resolution (:mod:`.mesh`), the inflow in time (``constant/boundaryData``) and
sets the time step and the simulated time in every file that holds them: the preCICE
time window and max-time (both coupling schemes), the fluid's ``deltaT`` and the solid's
``Time step size`` and ``End time``, which the deal.II adapter requires to agree.

Of the two solids in ``case/``, a run keeps one: the deal.II program (``solid-dealii/``,
the default) or the FEniCS bar that saves and restarts its state (``solid-fenics/``,
``solid.json`` its settings); both are participant ``Solid`` on ``Solid-Mesh``, so one
``precice-config.xml`` serves either.
"""

from __future__ import annotations

import json
import math
from typing import Any

from gymprecice_tutorials.case_files import apply_edits
from gymprecice_tutorials.turek_hron import CASE_DIR
from gymprecice_tutorials.turek_hron.mesh import GEOMETRY, RESOLUTIONS, blockmesh_dict

__all__ = ["INFLOW_MEAN", "RAMP_TIME", "SOLIDS", "case_files", "inflow", "inflow_files"]

#: each solid's directory (the solver kind is the key)
SOLIDS = {"dealii": "solid-dealii", "fenics": "solid-fenics"}

#: Turek and Hron's mean inflow (m/s) for FSI3, and the time over which it is ramped up
INFLOW_MEAN = 2.0
RAMP_TIME = 2.0
#: samples of the ramp in ``constant/boundaryData`` (OpenFOAM interpolates linearly)
RAMP_SAMPLE = 0.05
#: inlet points of ``constant/boundaryData`` across the channel
INLET_POINTS = 41

_MESH = "fluid-openfoam/system/blockMeshDict"
_XML = "precice-config.xml"
_PRM = "solid-dealii/parameters.prm"
_CONTROL = "fluid-openfoam/system/controlDict"


def inflow(y: float, t: float) -> float:
    """Turek and Hron's inflow (m/s) at height ``y`` and time ``t``: a parabola of mean
    :data:`INFLOW_MEAN`, ramped by ``(1 - cos(pi t / 2)) / 2`` until :data:`RAMP_TIME`."""
    h = GEOMETRY.height
    ramp = (1.0 - math.cos(math.pi * min(t, RAMP_TIME) / RAMP_TIME)) / 2.0
    return 1.5 * INFLOW_MEAN * 4.0 / h**2 * y * (h - y) * ramp


def inflow_files() -> dict[str, str]:
    """``constant/boundaryData/inlet``: the inlet's points and the inflow at sampled times.

    OpenFOAM's ``timeVaryingMappedFixedValue`` interpolates these in space and time, so
    the ramp needs no compiled code (``codedFixedValue``, which preCICE's tutorial uses,
    compiles at run time and is refused by installations that forbid it).
    """
    base = "fluid-openfoam/constant/boundaryData/inlet"
    half = GEOMETRY.depth / 2
    ys = [GEOMETRY.height * i / (INLET_POINTS - 1) for i in range(INLET_POINTS)]
    points = [(y, z) for z in (-half, half) for y in ys]

    def table(rows: list[str]) -> str:
        return f"{len(rows)}\n(\n" + "\n".join(rows) + "\n)\n"

    files = {f"{base}/points": table([f"(0 {y:.10g} {z:.10g})" for y, z in points])}
    steps = round(RAMP_TIME / RAMP_SAMPLE)
    times = [k * RAMP_SAMPLE for k in range(steps + 1)] + [1.0e4]  # then held
    for t in times:
        rows = [f"({inflow(y, t):.10g} 0 0)" for y, _ in points]
        files[f"{base}/{t:.10g}/U"] = table(rows)
    return files


def case_files(
    resolution: str = "coarse",
    time_step: float = 1e-3,
    end_time: float = 8.0,
    degree: int = 2,
    action_time: float = 0.02,
    solid: str = "dealii",
    solid_settings: dict[str, Any] | None = None,
    fluid_writes: tuple[float, int] | None = None,
) -> dict[str, str]:
    """The case's files (relative path -> text) for one run.

    ``resolution`` names a mesh of :data:`~.mesh.RESOLUTIONS`; ``time_step`` is the
    coupling's time window, the fluid's and the solid's step; ``end_time`` the simulated
    seconds; ``degree`` the solid's polynomial degree; an action lasts ``action_time``
    (a whole number of time windows); ``solid`` names one of :data:`SOLIDS`.
    ``solid_settings`` go into the FEniCS bar's ``solid.json`` (``start_state``,
    ``save_dir``, ``save_times``); ``fluid_writes`` ``(interval, keep)`` has the fluid
    write its state every ``interval`` simulated seconds and keep the last ``keep``
    (OpenFOAM's ``writeInterval`` and ``purgeWrite``): what a library of starts needs.
    """
    if resolution not in RESOLUTIONS:
        raise ValueError(f"resolution must be one of {sorted(RESOLUTIONS)}, got {resolution!r}")
    if solid not in SOLIDS:
        raise ValueError(f"solid must be one of {sorted(SOLIDS)}, got {solid!r}")
    if solid_settings and solid != "fenics":
        raise ValueError("solid_settings are the FEniCS bar's (solid='fenics')")
    if not (time_step > 0 and end_time > 0 and degree >= 1):
        raise ValueError("time_step and end_time must be positive and degree at least 1")
    windows = round(action_time / time_step)
    if windows < 1 or abs(windows * time_step - action_time) > 1e-9:
        raise ValueError(
            f"action_time {action_time} s must be a whole number of time windows of {time_step} s"
        )
    dropped = [f"{where}/" for kind, where in SOLIDS.items() if kind != solid]
    files: dict[str, str] = {}
    for path in sorted(CASE_DIR.rglob("*")):
        rel = path.relative_to(CASE_DIR).as_posix()
        if path.is_file() and "__pycache__" not in rel and not rel.startswith(tuple(dropped)):
            files[rel] = path.read_text()
    files[_MESH] = blockmesh_dict(RESOLUTIONS[resolution])
    files.update(inflow_files())
    step, end = f"{time_step:.10g}", f"{end_time:.10g}"
    edits = [
        (_XML, '<time-window-size value="0.001" />', f'<time-window-size value="{step}" />'),
        (_XML, '<max-time value="8.0" />', f'<max-time value="{end}" />'),
        (_CONTROL, "deltaT          0.001;", f"deltaT          {step};"),
    ]
    if fluid_writes is not None:
        interval, keep = fluid_writes
        edits += [
            (
                _CONTROL,
                "writeInterval   1;\npurgeWrite      0;",
                f"writeInterval   {interval:.10g};\npurgeWrite      {int(keep)};",
            ),
        ]
    if solid == "dealii":
        edits += [
            (_PRM, "set Time step size  = 0.001", f"set Time step size  = {step}"),
            (_PRM, "set End time        = 8", f"set End time        = {end}"),
            (_PRM, "set Polynomial degree = 2", f"set Polynomial degree = {degree}"),
        ]
    for rel, old, new in edits[:2]:  # both coupling schemes carry the window and the end
        if files[rel].count(old) != 2:
            raise ValueError(
                f"{CASE_DIR / rel}: expected {old!r} in both coupling schemes; update "
                "gymprecice_tutorials.turek_hron.case to the packaged case"
            )
        files[rel] = files[rel].replace(old, new)
    apply_edits(files, edits[2:], CASE_DIR, "gymprecice_tutorials.turek_hron.case", "edits")
    config = json.loads(files["gymprecice-config.json"])
    config["actions"]["windows"] = windows
    if solid == "fenics":
        solver = config["physics_simulation_engine"]["solvers"]["solid"]
        # the deal.II program's options (its divergence bound) are not the script's
        solver["kind"], solver["path"], solver["options"] = solid, SOLIDS[solid], {}
        settings = json.loads(files[f"{SOLIDS[solid]}/solid.json"])
        settings["degree"] = degree
        settings.update(solid_settings or {})
        files[f"{SOLIDS[solid]}/solid.json"] = json.dumps(settings) + "\n"
    files["gymprecice-config.json"] = json.dumps(config, indent=4) + "\n"
    return files
