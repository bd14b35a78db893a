"""Build a library of FSI3 starts (:mod:`.starts`) from one uncontrolled coupled run.

The run is :class:`~.environment.TurekHronEnv`'s, the env's ordinary machinery (the same
files, coupling and solvers as the validation), from rest to the last start with the
jets shut: the fluid writes its state every ``spacing`` seconds and keeps the last
``count`` (OpenFOAM's ``writeInterval`` and ``purgeWrite``), the FEniCS bar saves its
state at the start times, and the states are gathered into a new library folder::

    python -m gymprecice_tutorials.turek_hron.build_starts --out DIR \\
        [--resolution coarse] [--time-step 0.002] [--degree 2] \\
        [--first 6.0] [--count 12] [--spacing 0.02] [--smoke]

``--smoke``: three starts at 0.02 to 0.04 s, under a minute, that checks the mechanism
(the inflow has barely begun: nothing swings yet). A run that fails leaves no library
and keeps its run folder (``.<name>-run`` beside it) for its logs.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import time as clock
from pathlib import Path

import numpy as np

from gymprecice_tutorials.turek_hron.environment import TurekHronEnv
from gymprecice_tutorials.turek_hron.series import recorded_series, run_to_end
from gymprecice_tutorials.turek_hron.starts import (
    INDEX,
    UNCONTROLLED,
    StartLibrary,
    load,
    split,
    start_times,
)

__all__ = ["build", "main"]

#: the full library's default: twelve starts, one action apart, from t = 6 s (the swing
#: is periodic on the coarse mesh from about 6 s; 12 x 0.02 s covers its 0.19 s period)
FIRST, COUNT, SPACING = 6.0, 12, 0.02
#: ``--smoke``: three starts at 0.02, 0.03 and 0.04 s (20 windows of 2 ms)
SMOKE = (0.02, 3, 0.01)


def _time_dir(root: Path, value: float, tolerance: float) -> str | None:
    """The name of ``root``'s full time directory at ``value`` (s): the flow and the
    deformed mesh, not a directory of ``uniform/`` alone that coupling iterations leave."""
    for entry in root.iterdir():
        try:
            near = abs(float(entry.name) - value) <= tolerance
        except ValueError:
            continue
        if near and (entry / "U").is_file() and (entry / "polyMesh" / "points").is_file():
            return entry.name
    return None


def build(
    out: str | Path,
    *,
    resolution: str = "coarse",
    time_step: float = 0.002,
    degree: int = 2,
    first: float = FIRST,
    count: int = COUNT,
    spacing: float = SPACING,
    run_root: str | Path | None = None,
) -> StartLibrary:
    """Run the uncontrolled case to the last start and gather the states (the module)."""
    times = start_times(first, count, spacing)
    windows = spacing / time_step
    if abs(windows - round(windows)) > 1e-9:
        raise ValueError(f"spacing {spacing} s must be a whole number of time steps of {time_step}")
    target = Path(out).expanduser().resolve()
    if (target / INDEX).exists():
        raise FileExistsError(f"{target / INDEX}: a library is already there; choose another --out")
    scratch_root = run_root is None  # the run's own folder, removed once the library is made
    runs = Path(run_root) if run_root is not None else target.parent / f".{target.name}-run"
    env = TurekHronEnv(
        resolution=resolution,
        time_step=time_step,
        end_time=times[-1],
        degree=degree,
        action_time=spacing,
        solid="fenics",
        run_root=runs,
        solid_settings={"save_dir": "states", "save_times": times},
        fluid_writes=(spacing, count + 1),
    )
    try:
        env.reset(seed=0)
        run_to_end(env)
        series = recorded_series(env)
        fluid, solid = env.solver_dirs[env.FLUID], env.solver_dirs[env.SOLID]
        names: list[str] = []
        for value in times:
            name = _time_dir(fluid, value, 0.5 * time_step)
            state = solid / "states" / f"state-{value:.6f}.npz"
            if name is None or not state.is_file():
                raise RuntimeError(
                    f"the run saved no state at t = {value:g} s (fluid {fluid}, solid {state})"
                )
            names.append(name)
        scratch = target.parent / f".{target.name}-partial"
        shutil.rmtree(scratch, ignore_errors=True)
        for name, value in zip(names, times, strict=True):
            shutil.copytree(fluid / name, scratch / "fluid" / name)
            (scratch / "solid").mkdir(parents=True, exist_ok=True)
            shutil.copy2(
                solid / "states" / f"state-{value:.6f}.npz", scratch / "solid" / f"state-{name}.npz"
            )
        index = {
            "case": "FSI3 (Turek and Hron 2006), uncontrolled, FEniCS bar",
            "resolution": resolution,
            "time_step": time_step,
            "degree": degree,
            "times": names,
            "split": split(names),
        }
        (scratch / INDEX).write_text(json.dumps(index, indent=2) + "\n")
        late = series["time"] >= times[0] - 0.5 * time_step
        np.savez(scratch / UNCONTROLLED, **{k: v[late] for k, v in series.items()})
        target.parent.mkdir(parents=True, exist_ok=True)
        scratch.rename(target)
    finally:
        env.close()
    if scratch_root:
        shutil.rmtree(runs, ignore_errors=True)
    return load(target)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True, type=Path, help="the library's folder (new)")
    parser.add_argument("--resolution", default="coarse", help="the fluid mesh (default coarse)")
    parser.add_argument("--time-step", type=float, default=0.002, help="time window (s)")
    parser.add_argument("--degree", type=int, default=2, help="the bar's polynomial degree")
    parser.add_argument("--first", type=float, default=FIRST, help="the first start (s)")
    parser.add_argument("--count", type=int, default=COUNT, help="how many starts")
    parser.add_argument("--spacing", type=float, default=SPACING, help="between starts (s)")
    parser.add_argument("--smoke", action="store_true", help="three starts at 0.02 to 0.04 s")
    args = parser.parse_args(argv)
    first, count, spacing = SMOKE if args.smoke else (args.first, args.count, args.spacing)
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
        )
    except (OSError, ValueError, RuntimeError) as exc:
        print(f"gymprecice_tutorials.turek_hron.starts: {exc}", file=sys.stderr)
        return 1
    took = clock.monotonic() - started
    print(
        f"{len(library.times)} starts ({', '.join(library.times)} s) in {library.path}, "
        f"{took / 60:.1f} min; held out: {', '.join(library.split.get('eval', []))}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
