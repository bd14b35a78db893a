"""The uncoupled pre-run that develops the flow every episode starts from, and its cache.

Prepare's step 4 (see :mod:`gymprecice_openfoam.case`): run the application without the
preCICE function object up to the requested times, move its function-object output to
``postProcessing.prerun``, and share the result between identical cases through
:mod:`.prerun_cache`. It is apart because it is the one long-running, cached part of
preparing a case.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path
from typing import Any

from gymprecice.plugin import CaseError
from gymprecice_openfoam import control, prerun_cache
from gymprecice_openfoam.case_state import (
    PRERUN_OUTPUT,
    STORE,
    is_episode_output,
    post_entries,
    remove_path,
    time_names,
    time_roots,
)
from gymprecice_openfoam.installation import OpenFOAMInstallation, mpi_env, run_tool
from gymprecice_openfoam.mesh import processor_dirs


def _latest(root: Path) -> tuple[str, float]:
    names = time_names(root)
    if not names:
        raise CaseError(f"{root}: no time directory (e.g. 0/) with initial fields")
    name = max(names, key=names.__getitem__)
    return name, names[name]


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
                remove_path(target)
            shutil.move(str(entry), str(target))
        if not any(fo.iterdir()):
            fo.rmdir()
    if not any(post.iterdir()):
        post.rmdir()


def shared_prerun(
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
        post_before = post_entries(run_dir)
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
        if is_episode_output(name) or name in (STORE, "postProcessing", PRERUN_OUTPUT)
    ]
    parameters = {
        "application": app,
        "np": np_,
        "targets": targets,
        "prerun_args": extra_args,
        "openfoam": [str(inst.project_dir), inst.version],
    }
    key = prerun_cache.entry_key(
        run_dir,
        skip=skip,
        parameters=parameters,
        as_read={"system/controlDict": control.as_a_prerun_reads_it},
    )
    roots = {os.path.relpath(r, run_dir): r for r in time_roots(run_dir)}  # ".", "processor0"
    with prerun_cache.locked_entry(directory, key) as entry:
        if prerun_cache.restore(entry, run_dir) is not None:
            return
        before = {rel: set(time_names(r)) for rel, r in roots.items()}
        run()
        new = {rel: sorted(set(time_names(r)) - before[rel]) for rel, r in roots.items()}
        written = {rel: names for rel, names in new.items() if names}
        prerun_cache.store(entry, run_dir, written, f"log.prerun.{app}")
