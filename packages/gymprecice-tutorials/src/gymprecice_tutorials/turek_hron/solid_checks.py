"""The FEniCS bar against Turek and Hron's structural tests, and its restart.

FSI3's control environment starts its episodes from the swinging state, so its solid
must start from a saved state: ``case/solid-fenics/bar.py`` (legacy FEniCS) does, where
the deal.II program always starts from rest. Before it stands in a coupled run, the bar
alone is checked against the benchmark's structural tests (Turek & Hron 2006, CSM1 to
CSM3: the bar clamped at the cylinder, under gravity 2 m/s^2, without fluid):

* CSM1 and CSM2: the static displacement of point A, the tip's middle, for the soft
  bar (shear modulus 0.5 MPa) and for FSI3's (2 MPa);
* CSM3: the soft bar let go from rest, its free oscillation's mean, amplitude and
  frequency over the last ``--window`` seconds of 10 s.

And a restart: CSM3 run to ``RESTART_END`` with its state saved halfway, then again from
that state: the second run's series must be the first's from there on, to the last
digit.

    python -m gymprecice_tutorials.turek_hron.solid_checks [--tests CSM1,CSM2,CSM3]
        [--cells 36,4] [--degree 2] [--time-step 0.005] [--restart] [--json FILE]

Exits 1 when a figure misses its tolerance or the restart differs, 2 when the FEniCS
solver environment is missing (with the fix). Cost on one core: CSM1 and CSM2 a second
each, CSM3 about a minute, after FEniCS compiles its forms once (tens of seconds on a
fresh machine).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gymprecice_tutorials.turek_hron.reference import Figure, oscillation

__all__ = ["PUBLISHED_CSM", "compare_csm", "main", "restart_difference", "run_csm"]

SOLID_DIR = Path(__file__).with_name("case") / "solid-fenics"
#: CSM3's simulated seconds, and the window at its end the figures are measured over
CSM3_END = 10.0
WINDOW = 5.0
#: the restart check's end, and where its first run saves the state
RESTART_END = 0.5
RESTART_AT = 0.25

#: Turek & Hron (2006), tables 4 and 5 (finest mesh), point A's displacement in m and
#: CSM3's frequency in Hz. Tolerances: 2 % for every figure.
PUBLISHED_CSM: dict[str, dict[str, Figure]] = {
    "CSM1": {"dx": Figure(-7.187e-3, 0.02), "dy": Figure(-66.10e-3, 0.02)},
    "CSM2": {"dx": Figure(-0.469e-3, 0.02), "dy": Figure(-16.97e-3, 0.02)},
    "CSM3": {
        "dx_mean": Figure(-14.305e-3, 0.02),
        "dx_amplitude": Figure(14.305e-3, 0.02),
        "dx_frequency": Figure(1.0995, 0.02),
        "dy_mean": Figure(-63.607e-3, 0.02),
        "dy_amplitude": Figure(65.160e-3, 0.02),
        "dy_frequency": Figure(1.0995, 0.02),
    },
}


@dataclass(frozen=True)
class Settings:
    """The bar's discretisation: rectangles along x and y (each cut in four triangles),
    the element degree, and the time step of CSM3."""

    cells: tuple[int, int] = (36, 4)
    degree: int = 2
    time_step: float = 0.005


class SolidEnvironmentMissing(RuntimeError):
    """The FEniCS solver environment cannot run the bar; the message says how to fix it."""


def _python() -> str:
    try:
        from gymprecice_fenics.solver_env import probe
    except ImportError as exc:
        raise SolidEnvironmentMissing(
            f"the FEniCS bar needs gymprecice-fenics ({exc}): pip install gymprecice-fenics, "
            "then gymprecice install fenics"
        ) from None
    report = probe()
    if not report.ok:
        raise SolidEnvironmentMissing("; ".join(report.problems))
    return report.python


def run_csm(test: str, where: Path, settings: Settings = Settings(), *extra: str) -> dict[str, Any]:
    """Run ``csm.py TEST`` in the FEniCS interpreter in ``where`` and return its record."""
    python = _python()
    where.mkdir(parents=True, exist_ok=True)
    for name in ("bar.py", "csm.py"):
        shutil.copy2(SOLID_DIR / name, where / name)
    out = where / f"{test.lower()}.json"
    argv = [
        python,
        "csm.py",
        test,
        "--out",
        out.name,
        "--cells",
        ",".join(str(n) for n in settings.cells),
        "--degree",
        str(settings.degree),
        "--time-step",
        repr(settings.time_step),
        *extra,
    ]
    proc = subprocess.run(
        argv,
        cwd=where,
        capture_output=True,
        text=True,
        stdin=subprocess.DEVNULL,
        env={**os.environ, "OMP_NUM_THREADS": "1"},
        check=False,
    )
    if proc.returncode != 0:
        errors = [line for line in proc.stdout.splitlines() if line.startswith("*** ")]
        tail = "\n".join([*errors[-6:], *proc.stderr.splitlines()[-6:]])
        raise RuntimeError(f"{test} failed in {where} (exit {proc.returncode}):\n{tail}")
    return json.loads(out.read_text())


def compare_csm(record: dict[str, Any], window: float = WINDOW) -> dict[str, dict[str, Any]]:
    """Each published figure of the record's test: the run's value, the difference and
    whether it is within the tolerance."""
    test = record["test"]
    if test == "CSM3":
        time = np.asarray(record["time"])
        measured: dict[str, float] = {}
        for signal in ("dx", "dy"):
            swing = oscillation(time, np.asarray(record[signal]), window)
            measured[f"{signal}_mean"] = swing.mean
            measured[f"{signal}_amplitude"] = swing.amplitude
            measured[f"{signal}_frequency"] = swing.frequency
    else:
        measured = {"dx": float(record["dx"]), "dy": float(record["dy"])}
    rows = {}
    for name, figure in PUBLISHED_CSM[test].items():
        value = measured[name]
        rows[name] = {
            "published": figure.value,
            "run": value,
            "difference": value / figure.value - 1.0,
            "tolerance": figure.tolerance,
            "within": figure.passes(value),
        }
    return rows


def restart_difference(where: Path, settings: Settings = Settings()) -> float:
    """The largest difference of point A's displacement between CSM3 run through and
    CSM3 restarted from its state saved at :data:`RESTART_AT`, over what both ran."""
    state = str((where / "state.npz").resolve())
    end = ["--end", repr(RESTART_END)]
    through = run_csm(
        "CSM3", where / "through", settings, *end, "--save-at", repr(RESTART_AT), "--state", state
    )
    resumed = run_csm("CSM3", where / "resumed", settings, *end, "--state", state)
    n = len(resumed["time"])
    if n < 2 or abs(resumed["time"][0] - RESTART_AT) > settings.time_step / 2:
        raise RuntimeError(f"the restarted run began at t = {resumed['time'][0]}, not {RESTART_AT}")
    return max(
        float(np.max(np.abs(np.asarray(through[k][-n:]) - np.asarray(resumed[k]))))
        for k in ("time", "dx", "dy")
    )


def _table(results: dict[str, dict[str, dict[str, Any]]]) -> str:
    lines = [
        "| test | figure | published | this bar | difference | tolerance |",
        "| --- | --- | --- | --- | --- | --- |",
    ]
    for test, rows in results.items():
        for name, row in rows.items():
            unit = "Hz" if name.endswith("frequency") else "mm"
            scale = 1.0 if unit == "Hz" else 1e3
            mark = "" if row["within"] else " (out)"
            lines.append(
                f"| {test} | {name} | {row['published'] * scale:.5g} {unit} | "
                f"{row['run'] * scale:.5g} {unit} | {100 * row['difference']:+.2f} %{mark} | "
                f"{100 * row['tolerance']:.0f} % |"
            )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m gymprecice_tutorials.turek_hron.solid_checks",
        description=__doc__.splitlines()[0],
    )
    parser.add_argument("--tests", default="CSM1,CSM2,CSM3")
    parser.add_argument("--cells", default="36,4", help="rectangles along x,y")
    parser.add_argument("--degree", type=int, default=2)
    parser.add_argument("--time-step", type=float, default=0.005)
    parser.add_argument("--restart", action="store_true", help="also check the restart")
    parser.add_argument("--json", type=Path, default=None)
    parser.add_argument("--out", type=Path, default=None, help="run directory (default: temporary)")
    args = parser.parse_args(argv)
    tests = [t.strip().upper() for t in args.tests.split(",") if t.strip()]
    unknown = sorted(set(tests) - set(PUBLISHED_CSM))
    if unknown:
        parser.error(f"--tests: unknown {unknown}; choose from {sorted(PUBLISHED_CSM)}")
    try:
        nx, ny = (int(n) for n in args.cells.split(","))
    except ValueError:
        parser.error(f"--cells takes two whole numbers, x,y: got {args.cells!r}")
    settings = Settings((nx, ny), args.degree, args.time_step)
    root = args.out or Path(tempfile.mkdtemp(prefix="fsi3-solid-"))
    results: dict[str, dict[str, dict[str, Any]]] = {}
    report: dict[str, Any] = {"cells": [nx, ny], "degree": args.degree, "tests": {}}
    try:
        for test in tests:
            extra = ("--end", repr(CSM3_END)) if test == "CSM3" else ()
            record = run_csm(test, root / test.lower(), settings, *extra)
            results[test] = compare_csm(record)
            report["tests"][test] = {
                "figures": results[test],
                "dofs": record["dofs"],
                "wall_clock_s": record["wall_clock_s"],
            }
        restart = restart_difference(root / "restart", settings) if args.restart else None
    except SolidEnvironmentMissing as exc:
        print(f"solid_checks: {exc}", file=sys.stderr)
        return 2
    ok = all(row["within"] for rows in results.values() for row in rows.values())
    print(_table(results))
    if restart is not None:
        report["restart_max_difference"] = restart
        print(f"restart from the state at t = {RESTART_AT:g} s: largest difference {restart:.3g}")
        ok = ok and restart == 0.0
    report["within"] = ok
    print("every figure within its tolerance" if ok else "a check failed")
    if args.json is not None:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(report, indent=2) + "\n")
        cost = ", ".join(
            f"{test} {record['wall_clock_s']:g} s" for test, record in report["tests"].items()
        )
        setting = f"{nx} x {ny} rectangles, 4 triangles each, degree {args.degree}"
        args.json.with_suffix(".md").write_text(
            f"The FEniCS bar, {setting}; CSM3 with time step {args.time_step:g} s, its last "
            f"{WINDOW:g} s of {CSM3_END:g} s.\n\n{_table(results)}\n\nwall-clock: {cost}\n"
        )
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
