"""The drag floor of a cylinder case: the drag of its steady, symmetric base flow.

A controller that suppresses the vortex shedding drives the flow towards the steady
solution of the same equations, so that solution's drag is the most that suppressing the
shedding can save. Jets that blow and suck the same flow rate, or a spin, act
antisymmetrically: held steady, they add a side force, and that is how a policy can buy a
drag below this floor. A drag-reduction target means little without the floor; the
training case's is in docs/training.md.

The steady solution is unstable. A run from rest leaves it once the asymmetry of the
case has grown into shedding, and steady solvers (simpleFoam) pseudo-shed on these
meshes. This module therefore runs the case time-accurately with the cylinder moved to the
channel's mid-height. Mesh, inflow and jets are then mirror-symmetric and only round-off
seeds the instability, so the wake settles to the base flow seconds before shedding
starts. The move is 5 mm in a 0.41 m channel. Drag is even in the offset from
mid-height, so the move changes it at second order only. The developed shedding of the
two channels has the same mean drag (docs/training.md)::

    python -m gymprecice_tutorials.base_flow jet_cylinder_fast [--end-time 4] [--out DIR]
        [--baseline-cd 3.2195] [--figure PNG]
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from gymprecice_tutorials import recipes
from gymprecice_tutorials.recipes import CaseSpec
from gymprecice_tutorials.validate import have_openfoam, prepare_case, read_force_coeffs, run_case

__all__ = ["SYMMETRY_CL", "BaseFlow", "main", "plateau", "plot", "symmetric_spec"]

#: Largest |Cl| of a window that still counts as symmetric: 2 % of the shedding's lift
#: amplitude (about 1). A perturbation of that size changes the drag at second order.
SYMMETRY_CL = 0.02
#: Length (s) of the windows whose mean drag is compared: about 1.5 shedding periods.
WINDOW = 0.5
#: Largest change of the mean drag between the last two windows of a settled base flow;
#: the packaged cases settle to about 5e-4 per window before they shed.
SETTLED_DRIFT = 1e-3


@dataclass(frozen=True)
class BaseFlow:
    """The base flow's drag, read from the last symmetric window of a run."""

    cd: float
    #: mean Cd of this window minus that of the window before it: the convergence
    drift: float
    #: largest |Cl| in the window (below SYMMETRY_CL by construction)
    max_abs_cl: float
    window: tuple[float, float]


def symmetric_spec(
    name: str, *, end_time: float, n_procs: int = 1, **resolution: float
) -> CaseSpec:
    """The recipe ``name`` with its cylinder at mid-height, run uncoupled to ``end_time``.

    ``resolution``: :class:`~gymprecice_tutorials.recipes.Resolution` fields to change,
    e.g. the validation mesh's ``cells_per_jet=4, wall_cell=0.0075``.
    """
    spec = recipes.case_spec(name, end_time=float(end_time), write_interval=0.0, n_procs=n_procs)
    cx, _ = spec.geometry.centre
    geometry = replace(spec.geometry, centre=(cx, spec.geometry.height / 2))
    geometry.check()
    return replace(spec, geometry=geometry, resolution=replace(spec.resolution, **resolution))


def plateau(t: np.ndarray, cd: np.ndarray, cl: np.ndarray, *, window: float = WINDOW) -> BaseFlow:
    """The base flow from a run's force coefficients: the last symmetric window's mean Cd.

    Windows of ``window`` seconds are laid back to back after the first one (the start
    from rest, skipped). The last window whose |Cl| stays below :data:`SYMMETRY_CL`, with a
    symmetric window before it for the drift, is the base flow: the wake has settled most
    there, and the shedding has not yet begun.
    """
    t, cd, cl = (np.asarray(a, dtype=float) for a in (t, cd, cl))
    step = float(t[1] - t[0]) if len(t) > 1 else 0.0
    edges = np.arange(t[0] + window, t[-1] - window + step + 1e-9, window)  # whole windows
    windows = [(a, a + window) for a in edges]
    means, lifts = [], []  # per window: mean Cd, largest |Cl| (inf: an empty window)
    for a, b in windows:
        inside = (t >= a) & (t < b)
        means.append(float(cd[inside].mean()) if inside.any() else float("nan"))
        lifts.append(float(np.abs(cl[inside]).max()) if inside.any() else float("inf"))
    for k in range(len(windows) - 1, 0, -1):
        if lifts[k] < SYMMETRY_CL and lifts[k - 1] < SYMMETRY_CL:
            return BaseFlow(
                cd=means[k],
                drift=means[k] - means[k - 1],
                max_abs_cl=lifts[k],
                window=windows[k],
            )
    raise ValueError(
        f"the flow never stayed symmetric (|Cl| < {SYMMETRY_CL}) for two {window:g} s windows "
        f"between t = {t[0]:g} and {t[-1]:g} s: the run is too short for the wake to settle, "
        "or the case is not mirror-symmetric (a kick, an uneven mesh); run longer with "
        "--end-time, or check the case"
    )


def plot(
    coeffs: dict[str, np.ndarray],
    base: BaseFlow,
    path: Path,
    title: str,
    *,
    baseline_cd: float | None = None,
) -> None:
    """Cd and Cl against time, the window read as the base flow, the floor and the baseline."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t, cd, cl = coeffs["Time"], coeffs["Cd"], coeffs["Cl"]
    shown = t >= WINDOW  # the impulsive start dwarfs everything else
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
    top.plot(t[shown], cd[shown], lw=0.8, color="C0")
    top.axhline(base.cd, color="C2", lw=1, ls="--", label=f"base flow {base.cd:.4f}")
    if baseline_cd:
        top.axhline(baseline_cd, color="C3", lw=1, ls=":", label=f"uncontrolled {baseline_cd:g}")
    bottom.plot(t[shown], cl[shown], lw=0.8, color="C0")
    for ax in (top, bottom):
        ax.axvspan(*base.window, color="0.85", lw=0)
        ax.grid(alpha=0.3)
    top.set_ylabel("$C_D$")
    top.legend(loc="lower right", fontsize=8)
    bottom.set_ylabel("$C_L$")
    bottom.set_xlabel("t [s]")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m gymprecice_tutorials.base_flow",
        description="Drag of a cylinder case's steady, symmetric base flow (the floor of "
        "what suppressing the vortex shedding can save).",
    )
    parser.add_argument("case", choices=sorted(recipes.CASES), help="the case recipe")
    parser.add_argument("--end-time", type=float, default=4.0, help="simulated seconds")
    parser.add_argument("--out", type=Path, help="run directory (default: a temporary one)")
    parser.add_argument("--np", type=int, default=1, dest="n_procs", help="MPI ranks")
    recipes.add_resolution_options(parser)
    parser.add_argument(
        "--baseline-cd", type=float, help="the case's uncontrolled mean Cd: prints the gap"
    )
    parser.add_argument("--figure", type=Path, help="write the Cd/Cl figure here")
    args = parser.parse_args(argv)
    if not have_openfoam():
        print("OpenFOAM (blockMesh, pimpleFoam) is not on PATH", file=sys.stderr)
        return 2
    knobs = recipes.resolution_overrides(args)
    spec = symmetric_spec(args.case, end_time=args.end_time, n_procs=args.n_procs, **knobs)
    cells = recipes.block_counts(spec.geometry, spec.resolution).cells
    out = args.out or Path(tempfile.mkdtemp(prefix="gymprecice-base-flow-"))
    fluid = out / recipes.FLUID_DIR
    print(
        f"{args.case} with the cylinder at mid-height: {cells} cells, dt {spec.flow.dt}, "
        f"end time {spec.end_time} s, in {fluid}",
        flush=True,
    )
    if fluid.exists():
        shutil.rmtree(fluid)
    prepare_case(spec, fluid, kick=False)
    wall = run_case(fluid, spec.n_procs)
    coeffs = read_force_coeffs(fluid)
    try:
        base = plateau(coeffs["Time"], coeffs["Cd"], coeffs["Cl"])
    except ValueError as exc:
        print(f"{fluid}: {exc}", file=sys.stderr)
        return 1
    print(
        f"base-flow Cd {base.cd:.4f} over t = {base.window[0]:g} .. {base.window[1]:g} s "
        f"(drift {base.drift:+.4f} from the window before, max |Cl| {base.max_abs_cl:.1e}); "
        f"pimpleFoam {wall:.0f} s"
    )
    if abs(base.drift) > SETTLED_DRIFT:
        print(
            f"the drag still moved by {base.drift:+.4f} in the last {WINDOW:g} s: not settled; "
            "run longer with --end-time (the shedding starts after about 3.5 s on these cases)"
        )
    if args.baseline_cd:
        gap = 100.0 * (1.0 - base.cd / args.baseline_cd)
        print(f"floor: {gap:.2f} % below the uncontrolled mean Cd {args.baseline_cd:g}")
    if args.figure:
        title = (
            f"{args.case}, cylinder at mid-height ({cells} cells): "
            f"base-flow Cd {base.cd:.4f} in the shaded window"
        )
        plot(coeffs, base, args.figure, title, baseline_cd=args.baseline_cd)
        print(f"figure: {args.figure}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
