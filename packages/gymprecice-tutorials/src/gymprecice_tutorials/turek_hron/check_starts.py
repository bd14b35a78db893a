"""Does an episode from a library's start repeat the uncontrolled run it was saved from?

    python -m gymprecice_tutorials.turek_hron.check_starts [--starts DIR] [--start TIME]
        [--time S] [--against RUN_DIR] [--json FILE] [--out DIR]

A start is only as good as the restart from it: a kick at the first coupling window (a
deformed interface handed to preCICE, a first iterate relaxed towards zero) leaves the
bar swinging otherwise than the run it was saved from, and every episode would learn on
that kick. This command runs the registered env ``gymprecice/TurekHronFSI3-v0``,
made ``uncontrolled``, from start TIME of the library (default: its first) for S
seconds (default 0.2, about a period of the swing), and compares the tip's displacement,
the drag and the lift at every time window with the library's uncontrolled series
(``uncontrolled.npz``, which spans the starts: TIME + S must lie within it). Each
signal must stay within its tolerance (:data:`TOLERANCES`).

With ``--against RUN_DIR`` (the run folder of an uninterrupted run from rest, e.g.
``validate --solid fenics --time-step 0.002 --out RUN_DIR``), the library's own swing is
also compared with that run's over the starts' span: the tip's range and its upward
zero crossings. The library's run is made of segments, each restarted from the last's
checkpoint; the periodic swing forgets a restart's transient but may keep a phase shift,
which this shows.

Exits 1 when a signal misses its tolerance, 2 on bad input. Needs the real stack
(OpenFOAM, preCICE and the FEniCS solver environment) and a library of starts.
"""

from __future__ import annotations

import argparse
import json
import sys
import time as clock
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from gymprecice_tutorials.turek_hron import starts as start_library
from gymprecice_tutorials.turek_hron.reference import up_crossings
from gymprecice_tutorials.turek_hron.series import SIGNALS, Series, recorded_series

__all__ = ["TOLERANCES", "compare_with_series", "main", "swing_of"]

#: the largest departure from the uncontrolled series each signal may show, as a
#: fraction of the series' largest magnitude over the episode (tip: 0.1 % of its swing,
#: about 30 µm; forces: 0.5 %)
TOLERANCES = {"tip_dx": 1e-3, "tip_dy": 1e-3, "drag": 5e-3, "lift": 5e-3}
#: simulated seconds of the episode by default: about one period of the swing (5.3 Hz)
EPISODE_TIME = 0.2
#: the FEniCS bar's watch point log in a run folder of ``validate`` (or of an env)
WATCH_POINT_LOG = "env_0/solid-fenics/precice-Solid-watchpoint-Flap-Tip.log"


def compare_with_series(episode: Series, series: Series, start: float) -> dict[str, Any]:
    """Each signal of ``episode`` (times from its start at ``start``) against ``series``
    (the simulation's times) at every time window after the first step: the largest
    departure, the scale it is measured against and whether it is within tolerance. The
    forces of an episode begin at its first window's end, so time 0 is left out."""
    times = np.asarray(episode["time"], dtype=float)
    after = times > 0
    result: dict[str, Any] = {}
    for name in SIGNALS:
        expected = np.interp(times[after] + start, series["time"], series[name])
        got = np.asarray(episode[name], dtype=float)[after]
        scale = float(np.max(np.abs(expected))) or 1.0
        departure = float(np.max(np.abs(got - expected))) if got.size else float("nan")
        result[name] = {
            "max_departure": departure,
            "scale": scale,
            "relative": departure / scale,
            "tolerance": TOLERANCES[name],
            "ok": bool(departure / scale <= TOLERANCES[name]),
        }
    return result


def swing_of(time: np.ndarray, tip_dy: np.ndarray, span: tuple[float, float]) -> dict:
    """The tip's range (m) and upward zero crossings (s) over ``span``."""
    time, tip_dy = np.asarray(time, dtype=float), np.asarray(tip_dy, dtype=float)
    inside = (time >= span[0] - 1e-9) & (time <= span[1] + 1e-9)
    return {
        "tip_dy_min": float(tip_dy[inside].min()),
        "tip_dy_max": float(tip_dy[inside].max()),
        "up_crossings": [float(t) for t in up_crossings(time[inside], tip_dy[inside])],
    }


def _against(run_dir: Path, series: Series) -> dict[str, Any]:
    """The library's swing and an uninterrupted run's over the library's span."""
    log = run_dir / WATCH_POINT_LOG
    if not log.is_file():
        raise FileNotFoundError(
            f"{log}: no watch point log of the FEniCS bar; run `python -m "
            f"gymprecice_tutorials.turek_hron.validate --solid fenics --out {run_dir}` "
            "(the case the library was built from) or name that run's folder"
        )
    # columns: Time, Coordinate0, Coordinate1, Displacement0, Displacement1, ...
    table = np.loadtxt(log, skiprows=1, ndmin=2)
    span = (float(series["time"][0]), float(series["time"][-1]))
    if table[-1, 0] < span[1]:
        raise ValueError(f"{log}: ends at t = {table[-1, 0]:g} s, before the starts' {span[1]:g} s")
    return {
        "run": str(run_dir),
        "span": list(span),
        "library": swing_of(series["time"], series["tip_dy"], span),
        "uninterrupted": swing_of(table[:, 0], table[:, 4], span),
    }


def run_episode(library: start_library.StartLibrary, name: str, seconds: float, out: Path):
    """The uncontrolled episode from start ``name``: its series, and its wall-clock (s)."""
    import gymnasium as gym

    import gymprecice  # noqa: F401  (registers the ids)

    split = next(s for s, names in library.split.items() if name in names)
    began = clock.monotonic()
    env = gym.make(
        "gymprecice/TurekHronFSI3-v0",
        starts=library.path,
        episode_time=seconds,
        uncontrolled=True,
        run_root=out,
        disable_env_checker=True,
    )
    try:
        env.reset(seed=0, options={"split": split, "start": library.split[split].index(name)})
        shut = np.zeros(env.action_space.shape, dtype=np.float32)
        while True:
            *_, terminated, truncated, _ = env.step(shut)
            if terminated:
                raise RuntimeError(
                    f"the episode from the start at {name} s ended early at "
                    f"t = {env.unwrapped.time:g} s: see the solvers' logs in {out}"
                )
            if truncated:
                break
        series = recorded_series(env.unwrapped, start_time=float(name))
    finally:
        env.close()
    return series, clock.monotonic() - began


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--starts", type=Path, default=None, help="the library (default: the env's)"
    )
    parser.add_argument("--start", default=None, help="the start's time (default: the first)")
    parser.add_argument("--time", type=float, default=EPISODE_TIME, help="the episode (s)")
    parser.add_argument("--against", type=Path, default=None, help="an uninterrupted run's folder")
    parser.add_argument("--json", type=Path, default=None, help="write the figures here")
    parser.add_argument("--out", type=Path, default=Path("runs/fsi3/check-starts"))
    args = parser.parse_args(argv)
    prog = "gymprecice_tutorials.turek_hron.check_starts"
    try:
        library = start_library.load(args.starts or start_library.default_starts())
        name = args.start if args.start is not None else library.times[0]
        if name not in library.times:
            raise ValueError(f"no start at {name} s in {library.path}: {', '.join(library.times)}")
        series = dict(np.load(library.path / start_library.UNCONTROLLED))
        if float(name) + args.time > float(series["time"][-1]) + 1e-9:
            raise ValueError(
                f"{library.path / start_library.UNCONTROLLED} ends at "
                f"{float(series['time'][-1]):g} s: an episode of {args.time:g} s from {name} s "
                "goes past it; give a shorter --time or an earlier --start"
            )
        against = _against(args.against, series) if args.against else None
    except (OSError, ValueError) as exc:
        print(f"{prog}: {exc}", file=sys.stderr)
        return 2
    episode, wall = run_episode(library, name, args.time, args.out)
    figures = compare_with_series(episode, series, float(name))
    result = {
        # as given: the default library's folder is this machine's
        "library": str(args.starts) if args.starts else "the registered env's default",
        "start": name,
        "episode_time": args.time,
        "windows": int(len(episode["time"]) - 1),
        "wall_s": round(wall, 1),
        "signals": figures,
        "against": against,
    }
    for signal, figure in figures.items():
        print(
            f"{signal:7s} largest departure {figure['max_departure']:.3g} "
            f"({figure['relative']:.2g} of {figure['scale']:.4g}; tolerance "
            f"{figure['tolerance']:g}): {'ok' if figure['ok'] else 'MISSED'}"
        )
    if against:
        for key in ("library", "uninterrupted"):
            swing = against[key]
            crossings = ", ".join(f"{t:.4f}" for t in swing["up_crossings"])
            print(
                f"{key}: tip dy {swing['tip_dy_min'] * 1e3:.2f} to "
                f"{swing['tip_dy_max'] * 1e3:.2f} mm, up-crossings at {crossings} s"
            )
    print(f"{result['windows']} windows from {name} s in {wall / 60:.1f} min")
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(result, indent=2) + "\n")
    return 0 if all(f["ok"] for f in figures.values()) else 1


if __name__ == "__main__":
    raise SystemExit(main())
