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
"""

from __future__ import annotations

import json
import os
import shutil
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gymprecice.plugin import CaseError, ConfigError, LaunchSpec, SolverContext, solver_environment
from gymprecice_openfoam import checks, control, foamio, prerun_cache
from gymprecice_openfoam.installation import (
    OpenFOAMInstallation,
    find_openfoam,
    mpi_env,
    run_tool,
)
from gymprecice_openfoam.mesh import processor_dirs

STORE = ".gymprecice-openfoam"
PRERUN_OUTPUT = "postProcessing.prerun"
STATE_FILE = "state.json"

#: Top-level names an episode may leave behind (removed by reset unless prepare made them).
_PRECICE_DIRS = ("precice-run", "precice-profiling", "preCICE-output", "precice-output")


def _is_episode_output(name: str) -> bool:
    if name in _PRECICE_DIRS:
        return True
    if name.endswith(".xml"):
        return False
    return (
        name.startswith("log.")
        or name.endswith(".log")
        or (name.startswith("precice-") and (name.endswith((".log", ".json", ".txt"))))
    )


# --------------------------------------------------------------------------- time dirs


def time_names(root: Path) -> dict[str, float]:
    """Time directories of ``root`` (name -> value); ``constant`` and others excluded."""
    out: dict[str, float] = {}
    try:
        entries = list(os.scandir(root))
    except FileNotFoundError:
        return out
    for entry in entries:
        if not entry.is_dir():
            continue
        try:
            value = float(entry.name)
        except ValueError:
            continue
        if np.isfinite(value):
            out[entry.name] = value
    return out


def find_time(root: Path, value: float, tolerance: float) -> str | None:
    """Name of the time directory within ``tolerance`` of ``value`` (closest wins)."""
    best: tuple[float, str] | None = None
    for name, t in time_names(root).items():
        gap = abs(t - value)
        if gap <= tolerance and (best is None or gap < best[0]):
            best = (gap, name)
    return None if best is None else best[1]


def _roots(run_dir: Path) -> list[Path]:
    """Directories holding time directories: the case and each processor directory."""
    return [run_dir, *processor_dirs(run_dir)]


def _root_key(run_dir: Path, root: Path) -> str:
    return "case" if root == run_dir else root.name


# --------------------------------------------------------------------------- state


@dataclass
class PreparedCase:
    """What prepare did, kept in ``solver.state`` and in ``.gymprecice-openfoam/state.json``.

    The file lets a reset work in a process that did not run prepare (a respawned env).
    """

    application: str
    np: int
    initial_time: str
    delta_t: float = 0.0
    #: root key ("case", "processor0", ...) -> time directory names after prepare
    prepared_times: dict[str, list[str]] = field(default_factory=dict)
    snapshots: list[str] = field(default_factory=list)
    split: dict[str, list[str]] = field(default_factory=dict)
    #: run-dir relative path -> [size, mtime_ns] of every file in prepared time dirs
    manifest: dict[str, list[int]] = field(default_factory=dict)
    top_level: list[str] = field(default_factory=list)
    post_dirs: list[str] = field(default_factory=list)
    coupled: bool = True

    def save(self, run_dir: Path) -> None:
        store = run_dir / STORE
        store.mkdir(exist_ok=True)
        (store / STATE_FILE).write_text(json.dumps(asdict(self), indent=1, sort_keys=True))

    @classmethod
    def load(cls, run_dir: Path) -> PreparedCase | None:
        path = run_dir / STORE / STATE_FILE
        if not path.is_file():
            return None
        return cls(**json.loads(path.read_text()))

    @property
    def tolerance(self) -> float:
        return max(1e-9, 0.5 * self.delta_t)


def _state(solver: SolverContext) -> PreparedCase:
    state = solver.state.get("openfoam")
    if isinstance(state, PreparedCase):
        return state
    loaded = PreparedCase.load(Path(solver.run_dir))
    if loaded is None:
        raise CaseError(
            f"{solver.describe()}: {solver.run_dir} was not prepared (no {STORE}/{STATE_FILE}); "
            "prepare the case before reset or launch"
        )
    solver.state["openfoam"] = loaded
    return loaded


# --------------------------------------------------------------------------- prepare


def _check_run_dir(solver: SolverContext) -> Path:
    run_dir = Path(solver.run_dir).resolve()
    if run_dir == Path(solver.source_dir).resolve():
        raise CaseError(
            f"{solver.describe()}: run directory {run_dir} is the source case; gymprecice "
            "prepares and resets a copy and never writes into the source"
        )
    if not run_dir.is_dir():
        raise CaseError(f"{solver.describe()}: run directory {run_dir} does not exist")
    return run_dir


def _clean_outputs(run_dir: Path, keep: set[str]) -> None:
    for entry in os.scandir(run_dir):
        if entry.name in keep or not _is_episode_output(entry.name):
            continue
        _remove(Path(entry.path))


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path)
    else:
        path.unlink(missing_ok=True)


def ensure_mesh(run_dir: Path, inst: OpenFOAMInstallation, options: dict[str, Any]) -> str:
    """Generate ``constant/polyMesh`` when missing; return what was done ("" if nothing)."""
    mesh_dir = run_dir / "constant" / "polyMesh"
    if foamio.existing(mesh_dir / "faces") is not None:
        return ""
    if any(foamio.existing(p / "constant" / "polyMesh" / "faces") for p in processor_dirs(run_dir)):
        return ""  # shipped already decomposed
    if (run_dir / "system" / "blockMeshDict").is_file() or (mesh_dir / "blockMeshDict").is_file():
        run_tool(["blockMesh"], run_dir, "log.blockMesh", inst)
        return "blockMesh"
    geo = options.get("geo") or next(iter(sorted(run_dir.glob("*.geo"))), None)
    msh = options.get("msh") or next(iter(sorted(run_dir.glob("*.msh"))), None)
    if geo is not None and msh is None:
        gmsh = shutil.which("gmsh")
        if gmsh is None:
            raise CaseError(
                f"{run_dir / Path(geo).name}: a gmsh geometry but no mesh, and gmsh is not "
                "on PATH; install gmsh or ship constant/polyMesh"
            )
        msh = Path(geo).with_suffix(".msh").name
        run_tool(
            [gmsh, "-3", str(Path(geo).name), "-format", "msh2", "-o", msh],
            run_dir,
            "log.gmsh",
            inst,
        )
    if msh is not None:
        run_tool(["gmshToFoam", str(Path(msh).name)], run_dir, "log.gmshToFoam", inst)
        return "gmshToFoam"
    raise CaseError(
        f"{mesh_dir}: no mesh and no recipe (system/blockMeshDict, *.geo or *.msh); ship "
        "the mesh or a recipe to build it"
    )


def subdomains(run_dir: Path) -> int:
    """``numberOfSubdomains`` of ``system/decomposeParDict`` (1 without the file)."""
    path = run_dir / "system" / "decomposeParDict"
    if not path.is_file():
        return 1
    value = foamio.load(path).get("numberOfSubdomains", 1)
    try:
        return int(value)
    except (TypeError, ValueError):
        raise CaseError(f"{path}: numberOfSubdomains {value!r} is not an integer") from None


def decide_np(run_dir: Path, options: dict[str, Any]) -> int:
    """Processes for the run: option ``np`` (1 = serial), else decomposeParDict's count."""
    wanted = options.get("np")
    have = subdomains(run_dir)
    if wanted is None:
        return max(1, have)
    wanted = int(wanted)
    if wanted < 1:
        raise ConfigError(f"solver option np={wanted}: must be 1 (serial) or more")
    if wanted > 1 and wanted != have:
        path = run_dir / "system" / "decomposeParDict"
        raise CaseError(
            f"{path}: numberOfSubdomains is {have} but the solver option np={wanted}; "
            "make them agree (or drop np to use the dictionary's count)"
        )
    return wanted


def decompose(run_dir: Path, inst: OpenFOAMInstallation, np_: int) -> None:
    """Run decomposePar unless every processor directory already has a mesh."""
    procs = processor_dirs(run_dir)
    if len(procs) == np_ and all(
        foamio.existing(p / "constant" / "polyMesh" / "faces") for p in procs
    ):
        return
    run_tool(["decomposePar", "-force"], run_dir, "log.decomposePar", inst)


def _latest(root: Path) -> tuple[str, float]:
    names = time_names(root)
    if not names:
        raise CaseError(f"{root}: no time directory (e.g. 0/) with initial fields")
    name = max(names, key=names.__getitem__)
    return name, names[name]


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


def prerun(
    run_dir: Path,
    inst: OpenFOAMInstallation,
    app: str,
    np_: int,
    targets: list[float],
    *,
    timeout: float | None = None,
    extra_args: list[str] | None = None,
) -> None:
    """Run ``app`` uncoupled, writing a time directory at each of ``targets``.

    Each target is one segment restarted from the previous one's output, so every
    target time is written exactly (not just the nearest multiple of a write interval).
    """
    root = processor_dirs(run_dir)[0] if np_ > 1 else run_dir
    adjustable = bool(control.read_control_dict(run_dir).get("adjustTimeStep", False))
    program = inst.which(app)
    if program is None:
        raise CaseError(f"{app}: not found in the OpenFOAM environment ({inst.project_dir})")
    log = f"log.prerun.{app}"
    (run_dir / log).unlink(missing_ok=True)
    for target in targets:
        _, start = _latest(root)
        if target <= start:
            continue
        with control.uncoupled_control_dict(
            run_dir, end_time=target, start_time=start, adjustable=adjustable
        ) as clean:
            args = [*(extra_args or [])]
            if not clean:
                args.append("-noFunctionObjects")
            if np_ > 1:
                mpirun = inst.which("mpirun") or "mpirun"
                argv = [mpirun, "-np", str(np_), program, "-parallel", *args]
            else:
                argv = [program, *args]
            run_tool(
                argv,
                run_dir,
                log,
                inst,
                timeout=timeout,
                extra_env=mpi_env() if np_ > 1 else None,
                append=True,
            )


def _move_prerun_output(run_dir: Path, before: set[str]) -> None:
    post = run_dir / "postProcessing"
    if not post.is_dir():
        return
    for fo in sorted(post.iterdir()):
        if not fo.is_dir():
            continue
        for entry in sorted(fo.iterdir()):
            rel = f"{fo.name}/{entry.name}"
            if rel in before:
                continue
            target = run_dir / PRERUN_OUTPUT / rel
            target.parent.mkdir(parents=True, exist_ok=True)
            if target.exists():
                _remove(target)
            shutil.move(str(entry), str(target))
        if not any(fo.iterdir()):
            fo.rmdir()
    if not any(post.iterdir()):
        post.rmdir()


def _post_entries(run_dir: Path) -> set[str]:
    post = run_dir / "postProcessing"
    if not post.is_dir():
        return set()
    return {f"{fo.name}/{e.name}" for fo in post.iterdir() if fo.is_dir() for e in fo.iterdir()}


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
                _remove(entry)


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
    for r in _roots(run_dir):
        key = _root_key(run_dir, r)
        kept = set(old.prepared_times.get(key, []))
        for name in old.snapshots:
            src = run_dir / STORE / "times" / key / name
            if name not in kept and src.is_dir():
                _copy_tree(src, r / name)  # fresh, whatever an episode did to it
                out.setdefault(str(r), set()).add(name)
    return out


def _copy_tree(src: Path, dst: Path) -> None:
    if dst.exists():
        _remove(dst)
    shutil.copytree(src, dst, copy_function=shutil.copy2, symlinks=True)


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
        _shared_prerun(run_dir, inst, app, np_, sorted({*missing, prerun_end}), options)
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


def _shared_prerun(
    run_dir: Path,
    inst: OpenFOAMInstallation,
    app: str,
    np_: int,
    targets: list[float],
    options: dict[str, Any],
) -> None:
    """The pre-run, through :mod:`.prerun_cache` unless option ``prerun_cache`` is false."""
    extra_args = list(options.get("prerun_args", []))

    def run() -> None:
        post_before = _post_entries(run_dir)
        prerun(
            run_dir,
            inst,
            app,
            np_,
            targets,
            timeout=options.get("prerun_timeout"),
            extra_args=extra_args,
        )
        _move_prerun_output(run_dir, post_before)

    directory = prerun_cache.cache_dir(options)
    if directory is None:
        run()
        return
    skip = [
        name
        for name in os.listdir(run_dir)
        if _is_episode_output(name) or name in (STORE, "postProcessing", PRERUN_OUTPUT)
    ]
    parameters = {
        "application": app,
        "np": np_,
        "targets": targets,
        "prerun_args": extra_args,
        "openfoam": [str(inst.project_dir), inst.version],
    }
    key = prerun_cache.entry_key(run_dir, skip=skip, parameters=parameters)
    roots = {os.path.relpath(r, run_dir): r for r in _roots(run_dir)}  # ".", "processor0"
    with prerun_cache.locked_entry(directory, key) as entry:
        if prerun_cache.restore(entry, run_dir) is not None:
            return
        before = {rel: set(time_names(r)) for rel, r in roots.items()}
        run()
        new = {rel: sorted(set(time_names(r)) - before[rel]) for rel, r in roots.items()}
        written = {rel: names for rel, names in new.items() if names}
        prerun_cache.store(entry, run_dir, written, f"log.prerun.{app}")


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
    for r in _roots(run_dir):
        key = _root_key(run_dir, r)
        names = time_names(r)
        for name in snapshots:
            if name in names:
                _copy_tree(r / name, store / "times" / key / name)
        created = set(names) - before.get(str(r), set())
        keep = [n for n in names if n == initial or n not in snapshots or n not in created]
        for name in set(names) - set(keep):
            _remove(r / name)
        for name in keep:
            if name not in snapshots:
                _copy_tree(r / name, store / "times" / key / name)
            kept_dirs.append(r / name)
        prepared[key] = sorted(keep, key=float)
    return prepared, kept_dirs


def prepare_case(solver: SolverContext) -> PreparedCase:
    """Prepare ``solver.run_dir`` (see the module docstring); returns what was recorded."""
    run_dir = _check_run_dir(solver)
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
    _clean_outputs(run_dir, keep=set())
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
    before = {str(r): set(time_names(r)) - parked.get(str(r), set()) for r in _roots(run_dir)}

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
    state.post_dirs = sorted(_post_entries(run_dir))
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


# --------------------------------------------------------------------------- reset


def choose_start(
    state: PreparedCase,
    rng: np.random.Generator | None,
    split: str | None,
    start: int | None = None,
) -> str:
    """The episode's start time: the initial state, or a snapshot of the split.

    ``start`` (reset option ``"start"``) takes the split's snapshot of that index in time
    order, so that an evaluation can run every held-out start once; without it the
    snapshot is drawn with ``rng``.
    """
    if not state.snapshots:
        return state.initial_time
    if split in (None, "train", "eval"):
        pool = state.split.get(split or "train") or state.snapshots
    elif split == "validation":
        pool = state.split.get("validation") or []
        if not pool:
            raise ConfigError(
                "reset option split='validation': the case keeps no validation snapshots; "
                "set the solver option validation_fraction (e.g. 0.25) or give snapshots "
                "as {'train': [...], 'eval': [...], 'validation': [...]}"
            )
    elif split == "all":
        pool = state.snapshots
    else:
        raise ConfigError(
            f"reset option split={split!r}: use 'train' (default), 'eval', 'validation' or 'all'"
        )
    if start is not None:
        if isinstance(start, bool) or not isinstance(start, (int, np.integer)):
            raise ConfigError(f"reset option start={start!r}: must be an integer index")
        if not 0 <= int(start) < len(pool):
            raise ConfigError(
                f"reset option start={start}: split {split or 'train'!r} has {len(pool)} "
                f"snapshot(s) ({', '.join(pool)}); use 0 to {len(pool) - 1}"
            )
        return sorted(pool, key=float)[int(start)]
    generator = rng if rng is not None else np.random.default_rng()
    return pool[int(generator.integers(len(pool)))]


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
        src = run_dir / STORE / "times" / _root_key(run_dir, root) / name
        if not src.is_dir():
            raise CaseError(f"{src}: stored initial state missing; prepare the case again")
        _copy_tree(src, directory)


def reset_case(solver: SolverContext) -> str:
    """Return ``solver.run_dir`` to the episode's initial state; returns the start time."""
    run_dir = _check_run_dir(solver)
    state = _state(solver)
    start = choose_start(
        state,
        solver.rng,
        solver.reset_options.get("split"),
        solver.reset_options.get("start"),
    )
    tol = state.tolerance
    start_value = float(start)

    for r in _roots(run_dir):
        key = _root_key(run_dir, r)
        prepared = state.prepared_times.get(key)
        if prepared is None:
            continue  # a processor directory prepare did not see: not ours to manage
        for name in time_names(r):
            if name not in prepared and name != start:
                _remove(r / name)
        for name in prepared:
            _restore_time_dir(run_dir, r, name, state)
        if start not in prepared:
            src = run_dir / STORE / "times" / key / start
            if src.is_dir():
                _copy_tree(src, r / start)

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
                    _remove(entry)
            if not any(fo.iterdir()) and not any(k.startswith(fo.name + "/") for k in keep):
                fo.rmdir()
        if not any(post.iterdir()) and "postProcessing" not in state.top_level:
            post.rmdir()

    _clean_outputs(run_dir, keep=set(state.top_level))
    control.set_start(run_dir, start)
    solver.state["initial_time"] = start_value
    solver.state["start_time"] = start
    return start


# --------------------------------------------------------------------------- launch


def launch_spec(solver: SolverContext) -> LaunchSpec:
    """The coupled run: ``<app>`` or ``mpirun -np N <app> -parallel`` in the run dir."""
    run_dir = Path(solver.run_dir)
    state = _state(solver)
    inst = find_openfoam(bashrc=solver.options.get("openfoam_bashrc"))
    program = inst.which(state.application)
    if program is None:
        raise CaseError(
            f"{state.application}: not found in the OpenFOAM installation at {inst.project_dir}"
        )
    extra = [str(a) for a in solver.options.get("solver_args", [])]
    env = dict(inst.env)
    # the adapter built by `gymprecice install` (OpenFOAM dlopens it by bare name)
    env.update(solver_environment({**os.environ, **env}))
    if state.np > 1:
        mpirun = inst.which("mpirun")
        if mpirun is None:
            raise CaseError(
                f"{solver.describe()}: the case runs on {state.np} processes but mpirun is "
                "not on PATH; install MPI or set np=1"
            )
        mpi_args = [str(a) for a in solver.options.get("mpirun_args", [])]
        argv = [mpirun, "-np", str(state.np), *mpi_args, program, "-parallel", *extra]
        env.update(mpi_env())
    else:
        argv = [program, *extra]
    return LaunchSpec(argv=argv, cwd=run_dir, env=env, log_name=log_name(state.application))


def log_name(application: str) -> str:
    """Name of the episode's solver log in the run directory."""
    return f"log.{application}"
