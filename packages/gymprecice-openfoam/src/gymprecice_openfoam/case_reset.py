"""Reset a prepared run directory every episode (see :mod:`gymprecice_openfoam.case`).

It chooses the episode's start (the initial state, or a snapshot of the train, eval or
validation split) and puts the directory back to it: later time directories dropped,
changed files of the prepared ones restored from the store, late ``postProcessing``
output and the last episode's logs removed. It is apart from preparing because it runs
every episode, possibly in a process that never prepared the case.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from gymprecice.plugin import CaseError, SolverContext
from gymprecice.plugin import choose_start as shared_choose_start
from gymprecice_openfoam import control
from gymprecice_openfoam.case_state import (
    STORE,
    PreparedCase,
    check_run_dir,
    clean_outputs,
    copy_tree,
    prepared_state,
    remove_path,
    root_key,
    time_names,
    time_roots,
)

#: How to get a validation split, for a reset asking for one the case does not keep.
VALIDATION_HINT = (
    "set the solver option validation_fraction (e.g. 0.25) or give snapshots "
    "as {'train': [...], 'eval': [...], 'validation': [...]}"
)


def choose_start(
    state: PreparedCase,
    rng: np.random.Generator | None,
    split: str | None,
    start: int | None = None,
) -> str:
    """The episode's start time: the initial state, or a snapshot of the split.

    ``start`` (reset option ``"start"``) takes the split's snapshot of that index in time
    order, so that an evaluation can run every held-out start once; without it the
    snapshot is drawn with ``rng``. The choice is core's :func:`gymprecice.plugin.
    choose_start`, shared with the other plugins so that a solid restarting from saved
    states (the FEniCS plugin's ``starts``) picks the state saved with this snapshot.
    """
    if not state.snapshots:
        return state.initial_time
    return shared_choose_start(
        state.split,
        state.snapshots,
        rng,
        split,
        start,
        what="snapshot",
        validation_hint=VALIDATION_HINT,
        order=float,
    )


def _restore_time_dir(run_dir: Path, root: Path, name: str, state: PreparedCase) -> None:
    directory = root / name
    prefix = str(directory.relative_to(run_dir)) + os.sep
    expected = {k: v for k, v in state.manifest.items() if k.startswith(prefix)}
    intact = directory.is_dir()
    if intact:
        seen = 0
        for path in directory.rglob("*"):
            if not path.is_file():
                continue
            st = path.stat()
            if expected.get(str(path.relative_to(run_dir))) != [st.st_size, st.st_mtime_ns]:
                intact = False
                break
            seen += 1
        intact = intact and seen == len(expected)
    if not intact:
        src = run_dir / STORE / "times" / root_key(run_dir, root) / name
        if not src.is_dir():
            raise CaseError(f"{src}: stored initial state missing; prepare the case again")
        copy_tree(src, directory)


def reset_case(solver: SolverContext) -> str:
    """Return ``solver.run_dir`` to the episode's initial state; returns the start time."""
    run_dir = check_run_dir(solver)
    state = prepared_state(solver)
    start = choose_start(
        state,
        solver.rng,
        solver.reset_options.get("split"),
        solver.reset_options.get("start"),
    )
    tol = state.tolerance
    start_value = float(start)

    for r in time_roots(run_dir):
        key = root_key(run_dir, r)
        prepared = state.prepared_times.get(key)
        if prepared is None:
            continue  # a processor directory prepare did not see: not ours to manage
        for name in time_names(r):
            if name not in prepared and name != start:
                remove_path(r / name)
        for name in prepared:
            _restore_time_dir(run_dir, r, name, state)
        if start not in prepared:
            src = run_dir / STORE / "times" / key / start
            if src.is_dir():
                copy_tree(src, r / start)

    post = run_dir / "postProcessing"
    if post.is_dir():
        keep = set(state.post_dirs)
        for fo in list(post.iterdir()):
            if not fo.is_dir():
                continue
            for entry in list(fo.iterdir()):
                rel = f"{fo.name}/{entry.name}"
                try:
                    late = float(entry.name) >= start_value - tol
                except ValueError:
                    late = False
                if late or rel not in keep:
                    remove_path(entry)
            if not any(fo.iterdir()) and not any(k.startswith(fo.name + "/") for k in keep):
                fo.rmdir()
        if not any(post.iterdir()) and "postProcessing" not in state.top_level:
            post.rmdir()

    clean_outputs(run_dir, keep=set(state.top_level))
    control.set_start(run_dir, start)
    solver.state["initial_time"] = start_value
    solver.state["start_time"] = start
    return start
