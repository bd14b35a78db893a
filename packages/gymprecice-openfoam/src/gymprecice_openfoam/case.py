"""Prepare an OpenFOAM run directory once, reset it every episode, describe the launch.

Core has already copied the pristine case into ``solver.run_dir``; nothing here ever
writes outside that directory (``solver.source_dir`` is only compared against).

prepare (once per environment):
  1. clear stale outputs the copy may carry (logs, preCICE files);
  2. make the mesh when the case has a recipe but no ``constant/polyMesh``
     (``system/blockMeshDict`` -> blockMesh; a ``.geo`` -> gmsh + gmshToFoam; a ``.msh``
     -> gmshToFoam);
  3. decompose when the run is parallel (``np`` option or ``system/decomposeParDict``);
  4. optionally pre-run the application *uncoupled* (the preCICE function object removed
     from a temporary controlDict) to ``prerun_end_time``, a developed flow that becomes
     every episode's initial state; the pre-run's function-object output is moved to
     ``postProcessing.prerun`` so episode readers start clean;
  5. store copies of the initial-state time directories (and of optional ``snapshots``)
     in ``.gymprecice-openfoam/`` and record what the directory holds.

reset (every episode): restore that state: drop later time directories (also in
``processor*``), put back any changed file of the initial time directories, drop
``postProcessing`` output from the episode's start time on, solver logs and preCICE
output. With ``snapshots`` the start is drawn with ``solver.rng`` from a fixed
train/eval split chosen by ``env.reset(options={"split": "eval"})``; ``"start": k`` in the
options takes the split's k-th snapshot instead (every held-out start, one by one).

The steps live in modules of their own, re-exported here (the plugin and callers use
this module): :mod:`.case_state` (the store, time directories, :class:`PreparedCase`),
:mod:`.case_mesh` (steps 2 and 3), :mod:`.case_prerun` (step 4 and its cache),
:mod:`.case_prepare` (the steps in order, snapshots and their split),
:mod:`.case_reset` (the episode's start and the reset) and :mod:`.case_launch` (the
coupled run's command).
"""

from __future__ import annotations

from gymprecice_openfoam.case_launch import launch_spec, log_name
from gymprecice_openfoam.case_mesh import decide_np, decompose, ensure_mesh, subdomains
from gymprecice_openfoam.case_prepare import prepare_case, split_snapshots
from gymprecice_openfoam.case_prerun import prerun
from gymprecice_openfoam.case_reset import choose_start, reset_case
from gymprecice_openfoam.case_state import (
    PRERUN_OUTPUT,
    STATE_FILE,
    STORE,
    PreparedCase,
    find_time,
    time_names,
)

__all__ = [
    "PRERUN_OUTPUT",
    "STATE_FILE",
    "STORE",
    "PreparedCase",
    "choose_start",
    "decide_np",
    "decompose",
    "ensure_mesh",
    "find_time",
    "launch_spec",
    "log_name",
    "prepare_case",
    "prerun",
    "reset_case",
    "split_snapshots",
    "subdomains",
    "time_names",
]
