"""Build a library of FSI3 starts (:mod:`.starts`) from one uncontrolled coupled run.

The run is :class:`~.environment.TurekHronEnv`'s, the env's ordinary machinery (the same
files, coupling and solvers as the validation), from rest to the last start with the
jets shut: the fluid writes its state every ``spacing`` seconds and keeps the last
``count`` (OpenFOAM's ``writeInterval`` and ``purgeWrite``), the FEniCS bar saves its
state at the start times, and the states are gathered into a new library folder::

    python -m gymprecice_tutorials.turek_hron.build_starts [--out DIR] \\
        [--resolution coarse] [--time-step 0.002] [--degree 2] \\
        [--first 6.0] [--count 12] [--spacing 0.02] [--checkpoint-every 1.0] [--smoke]

The run takes about 70 minutes on 2 cores (:data:`.starts.BUILD_COST`, measured), so it
goes in segments: every
``--checkpoint-every`` simulated seconds its state is kept as a one-start library in the
run folder (``.<name>-run/checkpoints/``), and the next segment starts from it as an
episode starts from a start. The same command, run again after an interruption, goes on
from the newest checkpoint; the run folder is removed once the library is made.

Without ``--out`` the library goes where the registered env ``gymprecice/TurekHronFSI3-v0``
looks for it, :func:`.starts.default_starts`; an env given ``starts=DIR`` takes one from
elsewhere.

``--smoke``: three starts at 0.02 to 0.04 s after a checkpoint at 0.01 s, under two
minutes, that checks the mechanism (the inflow has barely begun: nothing swings yet).
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import time as clock
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gymprecice_openfoam.case import find_time
from gymprecice_tutorials.turek_hron.environment import TurekHronEnv
from gymprecice_tutorials.turek_hron.series import recorded_series, run_to_end
from gymprecice_tutorials.turek_hron.starts import (
    INDEX,
    UNCONTROLLED,
    StartLibrary,
    default_starts,
    load,
    split,
    start_times,
)

__all__ = ["build", "checkpoint_times", "main"]

#: the full library's default: twelve starts, one action apart, from t = 6 s (the swing
#: is periodic on the coarse mesh from about 6 s; 12 x 0.02 s covers its 0.19 s period)
FIRST, COUNT, SPACING = 6.0, 12, 0.02
#: simulated seconds between the run's checkpoints (a segment's cost: a few minutes)
CHECKPOINT_EVERY = 1.0
#: ``--smoke``: three starts at 0.02, 0.03 and 0.04 s (20 windows of 2 ms), after a
#: checkpoint at 0.01 s that the last segment starts from
SMOKE = (0.02, 3, 0.01, 0.01)


def _time_dir(root: Path, value: float, tolerance: float) -> str | None:
    """The name of ``root``'s full time directory at ``value`` (s): the flow and the
    deformed mesh, not a directory of ``uniform/`` alone that coupling iterations leave."""
    name = find_time(root, value, tolerance)
    if name is None or not (root / name / "U").is_file():
        return None
    return name if (root / name / "polyMesh" / "points").is_file() else None


@dataclass(frozen=True)
class _Case:
    """The case a library's states belong to."""

    resolution: str
    time_step: float
    degree: int


def checkpoint_times(first: float, every: float, spacing: float) -> list[float]:
    """The segments' ends before the first start: multiples of ``every`` (a whole number
    of ``spacing``, so the fluid's writes stay on the starts' grid) below ``first``;
    none for ``every`` 0."""
    if every <= 0:
        return []
    steps = every / spacing
    if abs(steps - round(steps)) > 1e-9:
        raise ValueError(f"--checkpoint-every {every} s must be a whole number of --spacing")
    count = int((first - 0.5 * spacing) // every)
    return [round(every * k, 9) for k in range(1, count + 1)]


def _segment(
    case: _Case,
    start: StartLibrary | None,
    times: list[float],
    action_time: float,
    writes: tuple[float, int],
    runs: Path,
    into: Path,
) -> None:
    """Run uncontrolled from ``start``'s one start (``None``: from rest) to the last of
    ``times``, the bar saving its state at ``times`` and the fluid writing as ``writes``
    says (every so many seconds, keeping the last so many), and gather those states into
    the new library ``into``; one state is a checkpoint, a start of every split."""
    began = float(start.times[0]) if start is not None else 0.0
    shared: dict[str, Any] = {
        "resolution": case.resolution,
        "time_step": case.time_step,
        "degree": case.degree,
        "action_time": action_time,
        "solid": "fenics",
        "run_root": runs,
        "solid_settings": {"save_dir": "states", "save_times": times},
        "fluid_writes": writes,
    }
    if start is None:
        env = TurekHronEnv(end_time=times[-1], **shared)
    else:
        env = TurekHronEnv(starts=start.path, episode_time=times[-1] - began, **shared)
    try:
        env.reset(seed=0, options=None if start is None else {"split": "train", "start": 0})
        run_to_end(env)
        series = recorded_series(env, start_time=began)
        series["time"] = series["time"] + began
        fluid, solid = env.solver_dirs[env.FLUID], env.solver_dirs[env.SOLID]
        names: list[str] = []
        for value in times:
            name = _time_dir(fluid, value, 0.5 * case.time_step)
            state = solid / "states" / f"state-{value:.6f}.npz"
            if name is None or not state.is_file():
                raise RuntimeError(
                    f"the run saved no state at t = {value:g} s (fluid {fluid}, solid {state})"
                )
            names.append(name)
        scratch = into.parent / f".{into.name}-partial"
        shutil.rmtree(scratch, ignore_errors=True)
        for name, value in zip(names, times, strict=True):
            shutil.copytree(fluid / name, scratch / "fluid" / name)
            (scratch / "solid").mkdir(parents=True, exist_ok=True)
            shutil.copy2(
                solid / "states" / f"state-{value:.6f}.npz", scratch / "solid" / f"state-{name}.npz"
            )
        index = {
            "case": "FSI3 (Turek and Hron 2006), uncontrolled, FEniCS bar",
            "resolution": case.resolution,
            "time_step": case.time_step,
            "degree": case.degree,
            "times": names,
            "split": {"train": names, "eval": names} if len(names) == 1 else split(names),
        }
        (scratch / INDEX).write_text(json.dumps(index, indent=2) + "\n")
        late = series["time"] >= times[0] - 0.5 * case.time_step
        np.savez(scratch / UNCONTROLLED, **{k: v[late] for k, v in series.items()})
        into.parent.mkdir(parents=True, exist_ok=True)
        if into.exists():  # what is there did not load (build refuses a whole library)
            shutil.rmtree(into)
        scratch.rename(into)
    finally:
        env.close()


def _newest_checkpoint(folder: Path, marks: list[float], case: _Case) -> StartLibrary | None:
    """The checkpoint of the latest mark a run before this one made whole, or ``None``."""
    for mark in reversed(marks):
        try:
            library = load(folder / f"{mark:g}")
            library.check(case.resolution, case.time_step, case.degree)
        except (OSError, ValueError, KeyError):
            continue
        return library
    return None


def _say(line: str) -> None:
    print(f"build_starts: {line}", flush=True)


def build(
    out: str | Path,
    *,
    resolution: str = "coarse",
    time_step: float = 0.002,
    degree: int = 2,
    first: float = FIRST,
    count: int = COUNT,
    spacing: float = SPACING,
    checkpoint_every: float = CHECKPOINT_EVERY,
) -> StartLibrary:
    """Run the uncontrolled case to the last start and gather the states (the module)."""
    times = start_times(first, count, spacing)
    windows = spacing / time_step
    if abs(windows - round(windows)) > 1e-9:
        raise ValueError(f"spacing {spacing} s must be a whole number of time steps of {time_step}")
    marks = checkpoint_times(first, checkpoint_every, spacing)
    target = Path(out).expanduser().resolve()
    if (target / INDEX).exists():
        raise FileExistsError(f"{target / INDEX}: a library is already there; choose another --out")
    if target.exists() and any(target.iterdir()):
        raise FileExistsError(f"{target}: not empty; --out names a new folder for the library")
    case = _Case(resolution, time_step, degree)
    runs = target.parent / f".{target.name}-run"
    checkpoints = runs / "checkpoints"
    start = _newest_checkpoint(checkpoints, marks, case)
    done = float(start.times[0]) if start is not None else 0.0
    if start is not None:
        _say(f"going on from the checkpoint at t = {done:g} s ({start.path})")
    for mark in (m for m in marks if m > done + 1e-9):
        began = clock.monotonic()
        into = checkpoints / f"{mark:g}"
        writes = (mark - done, 2)
        _segment(case, start, [mark], spacing, writes, runs / f"segment-{mark:g}", into)
        start, done = load(into), mark
        _say(f"t = {mark:g} s of {times[-1]:g} s, {(clock.monotonic() - began) / 60:.1f} min")
    writes = (spacing, count + 1)
    _segment(case, start, times, spacing, writes, runs / "segment-last", target)
    shutil.rmtree(runs, ignore_errors=True)
    return load(target)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--out",
        type=Path,
        default=default_starts(),
        help="the library's folder, new (default: where the registered env looks for it)",
    )
    parser.add_argument("--resolution", default="coarse", help="the fluid mesh (default coarse)")
    parser.add_argument("--time-step", type=float, default=0.002, help="time window (s)")
    parser.add_argument("--degree", type=int, default=2, help="the bar's polynomial degree")
    parser.add_argument("--first", type=float, default=FIRST, help="the first start (s)")
    parser.add_argument("--count", type=int, default=COUNT, help="how many starts")
    parser.add_argument("--spacing", type=float, default=SPACING, help="between starts (s)")
    parser.add_argument(
        "--checkpoint-every",
        type=float,
        default=CHECKPOINT_EVERY,
        help="simulated seconds between the run's checkpoints (0: none)",
    )
    parser.add_argument("--smoke", action="store_true", help="three starts at 0.02 to 0.04 s")
    args = parser.parse_args(argv)
    first, count, spacing, every = (
        SMOKE if args.smoke else (args.first, args.count, args.spacing, args.checkpoint_every)
    )
    started = clock.monotonic()
    try:
        library = build(
            args.out,
            resolution=args.resolution,
            time_step=args.time_step,
            degree=args.degree,
            first=first,
            count=count,
            spacing=spacing,
            checkpoint_every=every,
        )
    except (OSError, ValueError, RuntimeError) as exc:
        runs = args.out.expanduser().resolve()
        print(
            f"gymprecice_tutorials.turek_hron.build_starts: {exc}\n(the same command goes on "
            f"from the newest checkpoint in {runs.parent / f'.{runs.name}-run'})",
            file=sys.stderr,
        )
        return 1
    took = clock.monotonic() - started
    print(
        f"{len(library.times)} starts ({', '.join(library.times)} s) in {library.path}, "
        f"{took / 60:.1f} min; held out: {', '.join(library.split.get('eval', []))}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
