"""Prepare an OpenFOAM run directory once per environment (see :mod:`gymprecice_openfoam.case`).

It orders the steps (clean, mesh, decompose, pre-run), decides the episodes' initial
time and the snapshots with their train/eval/validation split, stores their copies and
records a :class:`~.case_state.PreparedCase`. The mesh and the pre-run live in
:mod:`.case_mesh` and :mod:`.case_prerun`; this module is what ties them together.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path
from typing import Any

from gymprecice.plugin import CaseError, ConfigError, SolverContext
from gymprecice_openfoam import checks, control
from gymprecice_openfoam.case_mesh import decide_np, decompose, ensure_mesh
from gymprecice_openfoam.case_prerun import shared_prerun
from gymprecice_openfoam.case_state import (
    STORE,
    PreparedCase,
    check_run_dir,
    clean_outputs,
    copy_tree,
    find_time,
    post_entries,
    remove_path,
    root_key,
    time_names,
    time_roots,
)
from gymprecice_openfoam.installation import OpenFOAMInstallation, find_openfoam
from gymprecice_openfoam.mesh import processor_dirs


def _start_of(run_dir: Path, root: Path, tolerance: float) -> str:
    """The time directory controlDict makes the case start from."""
    ctl = control.read_control_dict(run_dir)
    mode = str(ctl.get("startFrom", "startTime"))
    names = time_names(root)
    if not names:
        raise CaseError(f"{root}: no time directory (e.g. 0/) with initial fields")
    if mode == "latestTime":
        return max(names, key=names.__getitem__)
    if mode == "firstTime":
        return min(names, key=names.__getitem__)
    start = control.float_entry(run_dir, "startTime", 0.0)
    found = find_time(root, start, tolerance)
    if found is None:
        raise CaseError(
            f"{control.control_dict_path(run_dir)}: startTime {start:g} has no time "
            f"directory in {root}; available: {', '.join(sorted(names, key=names.get))}"
        )
    return found


def _drop_late_post(run_dir: Path, start: float) -> None:
    """Remove ``postProcessing/<name>/<t>`` with ``t >= start``: an episode from ``start``
    writes there, and OpenFOAM would overwrite or rename those files."""
    post = run_dir / "postProcessing"
    if not post.is_dir():
        return
    for fo in post.iterdir():
        if not fo.is_dir():
            continue
        for entry in list(fo.iterdir()):
            try:
                late = float(entry.name) >= start
            except ValueError:
                late = False
            if late:
                remove_path(entry)


def split_snapshots(names: list[str], options: dict[str, Any]) -> dict[str, list[str]]:
    """Fixed split: every m-th snapshot (in time order) is for evaluation.

    Interleaving spreads both sets over the phases of a periodic flow. ``eval_fraction``
    (default 0.25) sets m; ``snapshots={"train": [...], "eval": [...]}`` gives it outright.
    ``validation_fraction`` (default 0: none) takes a third set out of the training
    snapshots, for choosing among models: with n = 1 / fraction, the snapshot at index
    n/2 - 1 of every n (for a quarter, the one halfway between two held-out ones), so it
    too spreads over the phases and is never drawn by training.
    """
    if len(names) == 1:
        return {"train": list(names), "eval": list(names)}
    fraction = float(options.get("eval_fraction", 0.25))
    if not 0 < fraction < 1:
        raise ConfigError(f"solver option eval_fraction={fraction}: must be in (0, 1)")
    m = max(2, round(1 / fraction))
    ordered = sorted(names, key=float)
    evals = ordered[m - 1 :: m] or ordered[-1:]
    split = {"train": [n for n in ordered if n not in evals], "eval": evals}
    validation_fraction = float(options.get("validation_fraction", 0) or 0)
    if validation_fraction:
        if not 0 < validation_fraction < 1:
            raise ConfigError(
                f"solver option validation_fraction={validation_fraction}: must be in (0, 1)"
            )
        n = max(2, round(1 / validation_fraction))
        chosen = [name for name in ordered[max(0, n // 2 - 1) :: n] if name not in evals]
        train = [name for name in split["train"] if name not in chosen]
        if not chosen or not train:
            raise ConfigError(
                f"solver option validation_fraction={validation_fraction}: {len(ordered)} "
                "snapshot(s) leave no validation or no training snapshot; give more snapshots "
                "or a smaller fraction"
            )
        split = {"train": train, "eval": evals, "validation": chosen}
    return split


def _unpark_snapshots(run_dir: Path) -> dict[str, set[str]]:
    """Put back snapshots an earlier prepare moved into the store (prepare run twice).

    Returns, per root, the names put back: they count as written by this prepare, so
    they go back into the store instead of staying among the case's times.
    """
    old = PreparedCase.load(run_dir)
    if old is None:
        return {}
    out: dict[str, set[str]] = {}
    for r in time_roots(run_dir):
        key = root_key(run_dir, r)
        kept = set(old.prepared_times.get(key, []))
        for name in old.snapshots:
            src = run_dir / STORE / "times" / key / name
            if name not in kept and src.is_dir():
                copy_tree(src, r / name)  # fresh, whatever an episode did to it
                out.setdefault(str(r), set()).add(name)
    return out


def _manifest(run_dir: Path, dirs: list[Path]) -> dict[str, list[int]]:
    out: dict[str, list[int]] = {}
    for directory in dirs:
        for path in sorted(directory.rglob("*")):
            if path.is_file():
                st = path.stat()
                out[str(path.relative_to(run_dir))] = [st.st_size, st.st_mtime_ns]
    return out


def _snapshot_option(options: dict[str, Any]) -> tuple[list[float], dict[str, list[float]] | None]:
    """Snapshot times, and the explicit split when the option is ``{"train", "eval"}``
    (and optionally ``"validation"``)."""
    raw = options.get("snapshots") or []
    if isinstance(raw, dict):
        unknown = set(raw) - {"train", "eval", "validation"}
        if unknown:
            raise ConfigError(
                "solver option snapshots: keys must be 'train', 'eval' and optionally "
                f"'validation', not {sorted(unknown)}"
            )
        explicit = {key: [float(v) for v in values] for key, values in raw.items()}
        return [v for values in explicit.values() for v in values], explicit
    return [float(v) for v in raw], None


def _initial_time(
    run_dir: Path,
    root: Path,
    inst: OpenFOAMInstallation,
    app: str,
    np_: int,
    options: dict[str, Any],
    snap_values: list[float],
    tol: float,
) -> str:
    """Run the pre-run if asked and return the episodes' initial time directory."""
    prerun_end = options.get("prerun_end_time")
    if prerun_end is not None:
        prerun_end = float(prerun_end)
        missing = [v for v in snap_values if find_time(root, v, tol) is None and v <= prerun_end]
        shared_prerun(run_dir, inst, app, np_, sorted({*missing, prerun_end}), options)
        initial = find_time(root, prerun_end, tol)
        if initial is None:
            raise CaseError(
                f"{run_dir}/log.prerun.{app}: the pre-run did not write t={prerun_end:g} "
                f"in {root}; check the log and the controlDict times"
            )
        return initial
    if options.get("initial_time") is not None:
        wanted = float(options["initial_time"])
        initial = find_time(root, wanted, tol)
        if initial is None:
            raise CaseError(
                f"{root}: no time directory for initial_time={wanted:g}; available: "
                f"{', '.join(sorted(time_names(root), key=float))}"
            )
        return initial
    return _start_of(run_dir, root, tol)


def _snapshot_names(root: Path, values: list[float], tol: float) -> list[str]:
    names: list[str] = []
    for value in values:
        name = find_time(root, value, tol)
        if name is None:
            raise CaseError(
                f"{root}: snapshot t={value:g} is not a time directory (available: "
                f"{', '.join(sorted(time_names(root), key=float))}); pre-run past it "
                "(prerun_end_time) or ship it"
            )
        if name not in names:
            names.append(name)
    return names


def _store_times(
    run_dir: Path, initial: str, snapshots: list[str], before: dict[str, set[str]]
) -> tuple[dict[str, list[str]], list[Path]]:
    """Copy initial-state and snapshot time directories into the store.

    Snapshots this prepare wrote (and that are not the initial state) leave the case's
    times and live in the store only; every other time directory stays and is restored
    by reset. Returns the kept names per root and the directories to fingerprint.
    """
    store = run_dir / STORE
    if store.exists():
        shutil.rmtree(store)
    (store / "times").mkdir(parents=True)
    prepared: dict[str, list[str]] = {}
    kept_dirs: list[Path] = []
    for r in time_roots(run_dir):
        key = root_key(run_dir, r)
        names = time_names(r)
        for name in snapshots:
            if name in names:
                copy_tree(r / name, store / "times" / key / name)
        created = set(names) - before.get(str(r), set())
        keep = [n for n in names if n == initial or n not in snapshots or n not in created]
        for name in set(names) - set(keep):
            remove_path(r / name)
        for name in keep:
            if name not in snapshots:
                copy_tree(r / name, store / "times" / key / name)
            kept_dirs.append(r / name)
        prepared[key] = sorted(keep, key=float)
    return prepared, kept_dirs


def prepare_case(solver: SolverContext) -> PreparedCase:
    """Prepare ``solver.run_dir`` (see the module docstring); returns what was recorded."""
    run_dir = check_run_dir(solver)
    options = dict(solver.options)
    control.read_control_dict(run_dir)
    inst = find_openfoam(bashrc=options.get("openfoam_bashrc"))
    app = control.application(run_dir, options.get("application"))
    if inst.which(app) is None:
        raise CaseError(
            f"{control.control_dict_path(run_dir)}: application {app!r} is not in the "
            f"OpenFOAM installation at {inst.project_dir}; fix 'application' or PATH"
        )
    snap_values, explicit_split = _snapshot_option(options)
    clean_outputs(run_dir, keep=set())
    ensure_mesh(run_dir, inst, options)
    missing = checks.patch_problems(run_dir)
    if missing:
        raise CaseError("\n".join(missing))
    np_ = decide_np(run_dir, options)
    if np_ > 1:
        decompose(run_dir, inst, np_)
    delta_t = control.float_entry(run_dir, "deltaT", 0.0)
    tol = max(1e-9, 0.5 * delta_t)
    root = processor_dirs(run_dir)[0] if np_ > 1 else run_dir
    parked = _unpark_snapshots(run_dir)
    before = {str(r): set(time_names(r)) - parked.get(str(r), set()) for r in time_roots(run_dir)}

    initial = _initial_time(run_dir, root, inst, app, np_, options, snap_values, tol)
    _drop_late_post(run_dir, float(initial) - tol)
    snapshots = _snapshot_names(root, snap_values, tol)
    if explicit_split is not None:
        split = {k: _snapshot_names(root, v, tol) for k, v in explicit_split.items()}
    else:
        split = split_snapshots(snapshots, options) if snapshots else {}
    prepared, kept_dirs = _store_times(run_dir, initial, snapshots, before)

    control.set_start(run_dir, initial, end_time=_end_time(solver, float(initial), options))
    state = PreparedCase(
        application=app,
        np=np_,
        initial_time=initial,
        delta_t=delta_t,
        prepared_times=prepared,
        snapshots=snapshots,
        split=split,
        manifest=_manifest(run_dir, kept_dirs),
        coupled=control.has_adapter(run_dir),
    )
    state.post_dirs = sorted(post_entries(run_dir))
    state.top_level = sorted({*os.listdir(run_dir), STORE})
    state.save(run_dir)
    solver.state["openfoam"] = state
    solver.state["initial_time"] = float(initial)
    return state


def _end_time(solver: SolverContext, start: float, options: dict[str, Any]) -> float | None:
    """controlDict endTime that lets the coupling run to its end.

    OpenFOAM stops at its own endTime even if preCICE would go on, leaving the controller
    waiting; so when the preCICE configuration says how long the coupling lasts, the end
    is moved to at least ``start + coupling end`` (option ``end_time`` overrides).
    """
    if options.get("end_time") is not None:
        return float(options["end_time"])
    precice = solver.precice
    if precice is None or not solver.participant:
        return None
    try:
        duration = precice.end_time(solver.participant)
    except Exception:
        return None
    if duration is None:
        return None
    current = control.float_entry(solver.run_dir, "endTime", 0.0)
    wanted = start + float(duration)
    return wanted if current < wanted - 1e-12 * max(1.0, wanted) else None
