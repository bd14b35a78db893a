"""Physical validation of the cylinder case against Schäfer & Turek (1996), test 2D-2.

Runs the jet-cylinder recipe uncoupled (jets closed, preCICE adapter dropped) with
OpenFOAM's pimpleFoam until the vortex shedding is periodic, then compares the maximum drag
and lift coefficients and the Strouhal number with the benchmark's reference intervals::

    python -m gymprecice_tutorials.validate [--smoke] [--out DIR] [--np N] [--figure PNG]

``--smoke`` runs a coarse mesh for a short time (CI, under three minutes on two cores) and
checks only that the coefficients are finite, in a loose band, and that shedding has
started. The full run prints the comparison and exits non-zero when a value misses its
reference interval by more than the stated tolerance.

OpenFOAM is found, and its programs run, by the OpenFOAM plugin
(:func:`gymprecice_openfoam.find_openfoam`, :func:`gymprecice_openfoam.run_tool`); the
coefficients are read with :func:`gymprecice_openfoam.read_force_coeffs`.
"""

from __future__ import annotations

import argparse
import itertools
import math
import os
import re
import shutil
import sys
import tempfile
import time
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from gymprecice.plugin import CaseError
from gymprecice_openfoam import find_openfoam, mpi_env, run_tool
from gymprecice_openfoam import read_force_coeffs as openfoam_read_force_coeffs
from gymprecice_tutorials import recipes
from gymprecice_tutorials.recipes import CaseSpec, Resolution

#: Schäfer & Turek (1996), 2D-2 reference intervals
REFERENCE: dict[str, tuple[float, float]] = {
    "Cd_max": (3.22, 3.24),
    "Cl_max": (0.99, 1.01),
    "St": (0.295, 0.305),
}
#: allowed distance outside the reference interval (relative); the finest published
#: reference solutions give Cl_max = 0.987, i.e. 0.3 % below the interval
TOLERANCE: dict[str, float] = {"Cd_max": 0.01, "Cl_max": 0.01, "St": 0.01}


@dataclass(frozen=True)
class RunPlan:
    resolution: Resolution
    end_time: float


#: the full validation (docs/validation.md) and the CI smoke run
FULL = RunPlan(Resolution.fine(), end_time=7.0)
SMOKE = RunPlan(Resolution.coarse(), end_time=2.0)

#: start-up kick: jet1 blows radially outward with this speed (m/s) until KICK_TIME, then
#: ramps to closed over 0.05 s. It breaks the symmetry of the start from rest so that the
#: shedding develops sooner; from then on the jets are closed (the uncontrolled case).
KICK_SPEED = 0.5
KICK_TIME = 0.2


# --------------------------------------------------------------------------------------
# Running OpenFOAM
# --------------------------------------------------------------------------------------


def openfoam_environment(base: dict[str, str] | None = None) -> dict[str, str]:
    """Environment for the OpenFOAM programs: ``base`` (default ``os.environ``) with what
    the OpenFOAM plugin finds they need (``WM_PROJECT_DIR``, and ``PATH`` where it sources
    an ``etc/bashrc``: :func:`gymprecice_openfoam.find_openfoam`) and Open MPI allowed to
    run as root (containers). ``base`` unchanged but for that where OpenFOAM is not found.
    """
    try:
        env = find_openfoam(base).environ(base)
    except CaseError:
        env = dict(os.environ if base is None else base)
    for key, value in mpi_env().items():
        env.setdefault(key, value)
    return env


def have_openfoam() -> bool:
    """Whether OpenFOAM is installed with the programs the validation runs."""
    try:
        installation = find_openfoam()
    except CaseError:
        return False
    return all(installation.which(p) for p in ("blockMesh", "pimpleFoam"))


def prepare_case(spec: CaseSpec, fluid: Path, *, kick: bool = True) -> Path:
    """Write the uncoupled validation case: no preCICE adapter, no probes, optional kick."""
    recipes.write_fluid_case(spec, fluid, coupled=False)
    (fluid / "system" / "probes").write_text("// probes dropped for the validation run\n")
    if kick:
        u = fluid / "0" / "U"
        text = u.read_text()
        t0, t1 = KICK_TIME, KICK_TIME + 0.05
        table = (
            f"((0 (0 {KICK_SPEED:g} 0)) ({t0:g} (0 {KICK_SPEED:g} 0)) "
            f"({t1:g} (0 0 0)) (1e6 (0 0 0)))"
        )
        body = (
            "jet1\n    {\n        // start-up kick, then closed\n"
            "        type            uniformFixedValue;\n"
            f"        uniformValue    table {table};\n"
            "        value           uniform (0 0 0);\n    }"
        )
        text, n = re.subn(r"jet1\s*\{[^}]*\}", lambda _: body, text, count=1)
        if n != 1:
            raise ValueError(f"{u}: no jet1 boundary condition to kick")
        u.write_text(text)
    return fluid


def run_case(fluid: Path, n_procs: int) -> float:
    """Mesh and run an uncoupled OpenFOAM case; returns the solver's wall time. Each
    program runs through :func:`gymprecice_openfoam.run_tool` (its log in ``fluid``, a
    failure a :class:`~gymprecice.plugin.CaseError` quoting the log's tail)."""
    installation = find_openfoam()
    run_tool(["blockMesh"], fluid, "log.blockMesh", installation)
    if n_procs > 1:
        run_tool(["decomposePar", "-force"], fluid, "log.decomposePar", installation)
        cmd = ["mpirun", "-np", str(n_procs), "pimpleFoam", "-parallel"]
    else:
        cmd = ["pimpleFoam"]
    start = time.perf_counter()
    run_tool(cmd, fluid, "log.pimpleFoam", installation, extra_env=mpi_env())
    return time.perf_counter() - start


# --------------------------------------------------------------------------------------
# Reading and analysing the coefficients
# --------------------------------------------------------------------------------------


def read_force_coeffs(fluid: Path, name: str = "forceCoeffs") -> dict[str, np.ndarray]:
    """Time series of a forceCoeffs function object (all restarts, later ones win), by
    column name with the times as ``"Time"``: :func:`gymprecice_openfoam.read_force_coeffs`
    as a dict."""
    rows = openfoam_read_force_coeffs(fluid, name)
    return {"Time": rows.time, **{c: rows.column(c) for c in rows.columns}}


@dataclass
class SheddingStats:
    cd_max: float
    cd_mean: float
    cl_max: float
    cl_min: float
    strouhal: float
    period: float
    cycles: int
    #: relative change of the Cl peak over the analysed cycles (periodicity check)
    cl_peak_drift: float
    window: tuple[float, float]

    def as_dict(self) -> dict[str, float]:
        return {"Cd_max": self.cd_max, "Cl_max": self.cl_max, "St": self.strouhal}


def shedding_stats(
    t: np.ndarray,
    cd: np.ndarray,
    cl: np.ndarray,
    *,
    diameter: float = 0.1,
    u_mean: float = 1.0,
    cycles: int = 10,
    t_min: float | None = None,
) -> SheddingStats:
    """Max Cd, max Cl and Strouhal number over the last ``cycles`` full lift cycles.

    Cycles are delimited by upward zero crossings of Cl - mean(Cl) over the last third of
    the record (linearly interpolated); the Strouhal number is D / (T Umean) with T the mean
    cycle length. Fewer cycles are used when fewer are available (at least two). Data
    before ``t_min`` (default: none) are ignored, e.g. a start-up transient.
    """
    t, cd, cl = (np.asarray(a, dtype=float) for a in (t, cd, cl))
    if t_min is not None:
        keep = t >= t_min
        t, cd, cl = t[keep], cd[keep], cl[keep]
    if len(t) < 3:
        raise ValueError("fewer than two lift cycles: no periodic shedding in the record")
    tail = t >= t[0] + (t[-1] - t[0]) * 2 / 3
    offset = float(np.mean(cl[tail]))
    x = cl - offset
    up = np.nonzero((x[:-1] < 0) & (x[1:] >= 0))[0]
    crossings = t[up] - x[up] * (t[up + 1] - t[up]) / (x[up + 1] - x[up])
    if len(crossings) < 3:
        raise ValueError("fewer than two lift cycles: no periodic shedding in the record")
    crossings = crossings[-(cycles + 1) :]
    n = len(crossings) - 1
    period = float(np.mean(np.diff(crossings)))
    mask = (t >= crossings[0]) & (t <= crossings[-1])
    peaks = []
    for a, b in itertools.pairwise(crossings):
        sel = (t >= a) & (t <= b)
        peaks.append(float(np.max(cl[sel])))
    drift = abs(peaks[-1] - peaks[0]) / max(abs(peaks[-1]), 1e-12)
    return SheddingStats(
        cd_max=float(np.max(cd[mask])),
        cd_mean=float(np.mean(cd[mask])),
        cl_max=float(np.max(cl[mask])),
        cl_min=float(np.min(cl[mask])),
        strouhal=diameter / (period * u_mean),
        period=period,
        cycles=n,
        cl_peak_drift=drift,
        window=(float(crossings[0]), float(crossings[-1])),
    )


def deviation(value: float, interval: tuple[float, float]) -> float:
    """Relative distance of ``value`` outside ``interval`` (0 inside)."""
    lo, hi = interval
    if value < lo:
        return (lo - value) / lo
    if value > hi:
        return (value - hi) / hi
    return 0.0


def comparison_table(stats: SheddingStats) -> tuple[str, bool]:
    lines = [f"{'quantity':<8} {'computed':>10} {'reference':>15} {'outside':>9} {'tol':>6}"]
    ok = True
    for key, value in stats.as_dict().items():
        lo, hi = REFERENCE[key]
        dev = deviation(value, (lo, hi))
        good = dev <= TOLERANCE[key]
        ok &= good
        lines.append(
            f"{key:<8} {value:>10.4f} {f'{lo:g} - {hi:g}':>15} {100 * dev:>8.2f}% "
            f"{100 * TOLERANCE[key]:>5.1f}%  {'ok' if good else 'MISS'}"
        )
    return "\n".join(lines), ok


def plot(
    coeffs: dict[str, np.ndarray], stats: SheddingStats | None, path: Path, title: str
) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t, cd, cl = coeffs["Time"], coeffs["Cd"], coeffs["Cl"]
    fig, axes = plt.subplots(2, 2, figsize=(10, 5.2), sharex="col", width_ratios=(2, 1))
    start = t >= min(t[-1], 0.05)  # hide the impulsive start
    for row, (y, name, ref) in enumerate(
        ((cd, "$C_D$", REFERENCE["Cd_max"]), (cl, "$C_L$", REFERENCE["Cl_max"]))
    ):
        ax = axes[row, 0]
        ax.plot(t[start], y[start], lw=0.7, color="C0")
        ax.set_ylabel(name)
        ax.grid(alpha=0.3)
        zoom = axes[row, 1]
        if stats is not None:
            sel = (t >= stats.window[1] - 3 * stats.period) & (t <= stats.window[1])
            zoom.plot(t[sel], y[sel], lw=1.0, color="C0")
            zoom.axhspan(*ref, color="C1", alpha=0.35, lw=0, label="Schäfer-Turek max")
            # zoom on the maxima: at most 8 reference widths below the interval
            lo = max(float(np.min(y[sel])), ref[0] - 8 * (ref[1] - ref[0]))
            hi = max(float(np.max(y[sel])), ref[1])
            pad = 0.05 * (hi - lo)
            zoom.set_ylim(lo - pad, hi + pad)
            ax.axvspan(*stats.window, color="0.85", lw=0, label="analysed cycles")
        zoom.grid(alpha=0.3)
    if stats is not None:
        axes[0, 0].legend(loc="lower right", fontsize=8)
        axes[0, 1].legend(loc="lower right", fontsize=8)
        axes[0, 1].set_title(f"maxima, last 3 cycles (St = {stats.strouhal:.4f})", fontsize=9)
    cl_lim = float(np.max(np.abs(cl[start]))) * 1.1 if start.any() else 1.0
    axes[1, 0].set_ylim(-cl_lim, cl_lim)
    axes[1, 0].set_xlabel("t [s]")
    axes[1, 1].set_xlabel("t [s]")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


# --------------------------------------------------------------------------------------
# Entry point
# --------------------------------------------------------------------------------------


def validation_spec(
    *, smoke: bool, n_procs: int, end_time: float | None = None, **resolution: float
) -> CaseSpec:
    plan = SMOKE if smoke else FULL
    res = replace(plan.resolution, **resolution)
    return recipes.case_spec(
        "jet_cylinder",
        resolution=res,
        end_time=float(end_time if end_time is not None else plan.end_time),
        n_procs=n_procs,
        write_interval=0.0,
    )


def check_smoke(coeffs: dict[str, np.ndarray]) -> list[str]:
    """Loose checks of a short coarse run; returns the failures."""
    t, cd, cl = coeffs["Time"], coeffs["Cd"], coeffs["Cl"]
    late = t >= t[-1] / 2
    problems = []
    if not (np.all(np.isfinite(cd)) and np.all(np.isfinite(cl))):
        problems.append("non-finite force coefficients")
        return problems
    if not 2.0 < float(np.mean(cd[late])) < 4.5:
        problems.append(f"mean Cd {np.mean(cd[late]):.3f} outside (2, 4.5)")
    amp = 0.5 * float(np.ptp(cl[t >= t[-1] - 0.7]))
    if not 0.05 < amp < 2.0:
        problems.append(f"Cl amplitude {amp:.3f} over the last 0.7 s outside (0.05, 2)")
    return problems


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m gymprecice_tutorials.validate")
    parser.add_argument("--smoke", action="store_true", help="coarse and short (CI)")
    parser.add_argument("--out", type=Path, help="run directory (default: a temporary one)")
    parser.add_argument("--np", type=int, default=1, dest="n_procs", help="MPI ranks")
    parser.add_argument("--end-time", type=float, help="simulated seconds")
    recipes.add_resolution_options(parser)
    parser.add_argument("--figure", type=Path, help="write the Cd/Cl figure here")
    parser.add_argument("--reuse", action="store_true", help="analyse an existing --out run")
    parser.add_argument("--no-kick", action="store_true", help="start from rest, no kick")
    args = parser.parse_args(argv)

    if not have_openfoam():
        print("OpenFOAM (blockMesh, pimpleFoam) is not on PATH", file=sys.stderr)
        return 2
    knobs = recipes.resolution_overrides(args)
    spec = validation_spec(smoke=args.smoke, n_procs=args.n_procs, end_time=args.end_time, **knobs)
    counts = recipes.block_counts(spec.geometry, spec.resolution)
    out = args.out or Path(tempfile.mkdtemp(prefix="gymprecice-validate-"))
    fluid = out / recipes.FLUID_DIR
    print(
        f"{'smoke' if args.smoke else 'full'} validation: {counts.cells} cells "
        f"({spec.resolution}), end time {spec.end_time} s, dt {spec.flow.dt}, "
        f"{spec.n_procs} rank(s), in {fluid}",
        flush=True,
    )
    wall = math.nan
    if not args.reuse:
        if fluid.exists():
            shutil.rmtree(fluid)
        prepare_case(spec, fluid, kick=not args.no_kick)
        wall = run_case(fluid, spec.n_procs)
        print(f"pimpleFoam wall time: {wall:.0f} s", flush=True)
    coeffs = read_force_coeffs(fluid)
    d, u = spec.geometry.diameter, spec.flow.u_mean

    if args.smoke:
        problems = check_smoke(coeffs)
        try:
            stats: SheddingStats | None = shedding_stats(
                coeffs["Time"],
                coeffs["Cd"],
                coeffs["Cl"],
                diameter=d,
                u_mean=u,
                t_min=0.5 * float(coeffs["Time"][-1]),
            )
        except ValueError:
            stats = None
        if stats is not None:
            print(
                f"Cd_max {stats.cd_max:.3f}  Cl_max {stats.cl_max:.3f}  "
                f"St {stats.strouhal:.3f} (last {stats.cycles} cycles, not converged)"
            )
        if args.figure:
            plot(coeffs, stats, args.figure, "smoke run (coarse mesh)")
        for p in problems:
            print(f"FAIL: {p}", file=sys.stderr)
        print("smoke validation", "failed" if problems else "passed")
        return 1 if problems else 0

    stats = shedding_stats(coeffs["Time"], coeffs["Cd"], coeffs["Cl"], diameter=d, u_mean=u)
    table, ok = comparison_table(stats)
    print(
        f"analysed {stats.cycles} lift cycles, t = {stats.window[0]:.3f} .. "
        f"{stats.window[1]:.3f} s; Cl peak drift {100 * stats.cl_peak_drift:.2f} %; "
        f"mean Cd {stats.cd_mean:.4f}; Cl min {stats.cl_min:.4f}"
    )
    print(table)
    if args.figure:
        title = (
            f"Schäfer-Turek 2D-2 (Re = 100), pimpleFoam, {counts.cells} cells: "
            f"Cd_max {stats.cd_max:.3f}, Cl_max {stats.cl_max:.3f}, St {stats.strouhal:.4f}"
        )
        plot(coeffs, stats, args.figure, title)
        print(f"figure: {args.figure}")
    if stats.cl_peak_drift > 0.01:
        print("WARNING: the shedding is not yet periodic (Cl peaks drift by > 1 %)")
        ok = False
    print("validation", "passed" if ok else "FAILED")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())


__all__ = [
    "FULL",
    "REFERENCE",
    "SMOKE",
    "TOLERANCE",
    "RunPlan",
    "SheddingStats",
    "check_smoke",
    "comparison_table",
    "deviation",
    "have_openfoam",
    "main",
    "openfoam_environment",
    "prepare_case",
    "read_force_coeffs",
    "run_case",
    "shedding_stats",
    "validation_spec",
]
