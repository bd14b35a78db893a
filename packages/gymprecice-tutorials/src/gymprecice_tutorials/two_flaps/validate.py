"""The two flaps uncontrolled, against preCICE's tutorial, and one run's cost by participant.

``python -m gymprecice_tutorials.two_flaps.validate`` runs the coupled case with both
slots closed (the tutorial's plain floor) from the impulsive start, on the packaged case
(the tutorial's mesh, time window and coupling) and on the training case, and prints:

* both flaps' tip displacement ``dx`` over time, side by side, from the solids' watch
  points (the tutorial's ``Flap-Tip``);
* the comparison with the tutorial's one documented result: its figure of the flow and
  the bent flaps at t = 2.3 s (:data:`FIGURE_AT_2_3_S`, measured on the published image,
  one pixel = 0.0056 m), the only reference the tutorial gives (it ships no reference
  results and no displacement plot);
* the first swing of each flap (peak and time) and its period, packaged against training
  case;
* where one run's wall-clock goes: each participant's own computing (preCICE's profiling
  event ``solver.advance``), its time inside preCICE's ``advance`` (data exchange,
  mapping, acceleration and waiting for the others), the controller's own code and its
  waiting (the env's ``info["timing"]``), and the coupling iterations per window (the
  Fluid's ``precice-Fluid-iterations.log``).

``--csv FILE`` writes the time series; ``--plot FILE`` draws them (matplotlib).
"""

from __future__ import annotations

import argparse
import csv
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gymprecice_tutorials.case_files import write_case_files
from gymprecice_tutorials.two_flaps.environment import FLAPS, TwoFlapsEnv
from gymprecice_tutorials.two_flaps.training_case import fast_case_files, packaged_case_files

__all__ = ["FIGURE_AT_2_3_S", "Run", "main", "profile_totals", "run_uncontrolled"]

#: tip displacement dx (m) of each flap at t = 2.3 s, read off the tutorial's figure
#: (images/tutorials-multiple-perpendicular-flaps-results.png: the centre line of the
#: drawn solid at its tip against its base, 178 pixels per metre)
FIGURE_AT_2_3_S = {"upstream": 0.012, "downstream": 0.013}
FIGURE_UNCERTAINTY = 0.006
_PARTICIPANTS = ("Fluid", *(flap.participant for flap in FLAPS))


@dataclass
class Run:
    """One uncontrolled run: time series and what it cost."""

    name: str
    time: np.ndarray
    dx: dict[str, np.ndarray]
    wall_s: float
    reset_s: float
    controller_env_s: float
    controller_wait_s: float
    profile: dict[str, dict[str, float]] = field(default_factory=dict)
    iterations: float | None = None


def run_uncontrolled(name: str, files: dict[str, str], end_time: float, run_root: Path) -> Run:
    """Run ``files`` (a two-flap case ending at ``end_time``) with both slots closed."""
    case = write_case_files(f"two-flaps-validate-{name}", files, run_root)
    started = time.perf_counter()
    env = TwoFlapsEnv(case, 0, run_root=run_root / name)
    env_s = wait_s = 0.0
    try:
        env.reset(seed=0)
        reset_s = time.perf_counter() - started
        while env.agents:
            _, _, _, _, infos = env.step({agent: np.zeros(1, np.float32) for agent in env.agents})
            timing = infos["upstream"]["timing"]
            env_s += timing["env_s"]
            wait_s += timing["wait_s"]
        logs = {flap.agent: env._tips[flap.agent] for flap in FLAPS}
        data = {agent: log.data.copy() for agent, log in logs.items()}
        fields = {
            flap.agent: logs[flap.agent].field(flap.displacement, data[flap.agent])[:, 0]
            for flap in FLAPS
        }
    finally:
        env.close()
    wall = time.perf_counter() - started
    run_dir = env.run_dir
    return Run(
        name=name,
        time=data["upstream"][:, 0],
        dx=fields,
        wall_s=wall,
        reset_s=reset_s,
        controller_env_s=env_s,
        controller_wait_s=wait_s,
        profile={p: profile_totals(run_dir, p) for p in _PARTICIPANTS},
        iterations=_mean_iterations(run_dir),
    )


def profile_totals(run_dir: Path, participant: str) -> dict[str, float]:
    """Seconds of ``solver.advance``, ``advance`` and ``initialize`` in a participant's
    preCICE profiling file (``precice-profiling/<participant>-0-1.txt``, v3's text form)."""
    files = sorted(Path(run_dir).rglob(f"precice-profiling/{participant}-*.txt"))
    totals = {"solver.advance": 0.0, "advance": 0.0, "initialize": 0.0}
    for path in files[:1]:
        names: dict[str, str] = {}
        began: dict[str, int] = {}
        for line in path.read_text().splitlines()[1:]:
            kind, _, rest = line.partition(":")
            key = kind[1:]
            if kind.startswith("N"):
                names[key] = rest
            elif kind.startswith("B"):
                began[key] = int(rest.split(":")[0])
            elif kind.startswith("E") and key in began:
                name = names.get(key)
                if name in totals:
                    totals[name] += (int(rest.split(":")[0]) - began.pop(key)) / 1e6
    return totals


def _mean_iterations(run_dir: Path) -> float | None:
    logs = sorted(Path(run_dir).rglob("precice-Fluid-iterations.log"))
    if not logs:
        return None
    rows = [line.split() for line in logs[0].read_text().splitlines()[1:] if line.strip()]
    values = [float(row[2]) for row in rows if len(row) > 2]
    return float(np.mean(values)) if values else None


def _at(run: Run, agent: str, t: float) -> float:
    return float(np.interp(t, run.time, run.dx[agent]))


def _first_peak(run: Run, agent: str) -> tuple[float, float]:
    dx = run.dx[agent]
    k = int(np.argmax(np.abs(dx[run.time <= 1.5]))) if len(dx) else 0
    return float(run.time[k]), float(dx[k])


def _period(run: Run, agent: str) -> float | None:
    """Twice the mean spacing of the crossings of the mean, after the first 0.3 s."""
    keep = run.time > 0.3
    t, x = run.time[keep], run.dx[agent][keep]
    if len(x) < 4:
        return None
    x = x - x.mean()
    crossings = [
        t[i] - x[i] * (t[i + 1] - t[i]) / (x[i + 1] - x[i])
        for i in range(len(x) - 1)
        if x[i] * x[i + 1] < 0
    ]
    return 2.0 * float(np.mean(np.diff(crossings))) if len(crossings) > 1 else None


def report(runs: Sequence[Run]) -> str:
    """The comparison and the cost table, as printed."""
    lines = ["tip displacement dx (m), both slots closed, from the impulsive start"]
    header = "  t (s)" + "".join(f"  {r.name + ' ' + a:>22}" for r in runs for a in ("up", "down"))
    lines.append(header)
    end = min(float(r.time[-1]) for r in runs)
    for t in np.arange(0.25, end + 1e-9, 0.25):
        values = "".join(
            f"  {_at(r, a, t):>22.4f}" for r in runs for a in ("upstream", "downstream")
        )
        lines.append(f"  {t:5.2f}{values}")
    if end >= 2.3:
        lines.append(
            f"\nat t = 2.3 s, the tutorial's figure (± {FIGURE_UNCERTAINTY} m, one pixel):"
        )
        for agent, value in FIGURE_AT_2_3_S.items():
            ours = ", ".join(f"{r.name} {_at(r, agent, 2.3):.4f}" for r in runs)
            lines.append(f"  {agent:<10} figure {value:.3f}   {ours}")
    lines.append("\nfirst swing (largest |dx| before 1.5 s) and period (s)")
    for r in runs:
        for agent in ("upstream", "downstream"):
            t, x = _first_peak(r, agent)
            period = _period(r, agent)
            lines.append(
                f"  {r.name:<9} {agent:<10} peak {x:+.4f} m at {t:.2f} s, period "
                + (f"{period:.2f}" if period else "n/a")
            )
    lines.append("\ncost of one run (s of wall-clock; the machine's load inflates them)")
    for r in runs:
        flow = float(r.time[-1])
        lines.append(
            f"  {r.name}: {flow:g} s of flow in {r.wall_s:.1f} s (reset, with mesh and start, "
            f"{r.reset_s:.1f} s); {r.iterations or float('nan'):.2f} coupling iterations "
            "per window"
        )
        for participant, totals in r.profile.items():
            lines.append(
                f"    {participant:<17} computing {totals['solver.advance']:7.1f}   in "
                f"preCICE advance {totals['advance']:7.1f}   initialize "
                f"{totals['initialize']:5.1f}"
            )
        lines.append(
            f"    {'Controller':<17} own code  {r.controller_env_s:7.1f}   waiting for the "
            f"solvers {r.controller_wait_s:7.1f}"
        )
    return "\n".join(lines)


def _write_csv(runs: Sequence[Run], path: Path) -> None:
    with path.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["case", "time", "upstream_dx", "downstream_dx"])
        for r in runs:
            for k, t in enumerate(r.time):
                writer.writerow([r.name, f"{t:.6g}", r.dx["upstream"][k], r.dx["downstream"][k]])


def _plot(runs: Sequence[Run], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 1, sharex=True, figsize=(7, 5))
    for ax, agent in zip(axes, ("upstream", "downstream"), strict=True):
        for r in runs:
            ax.plot(r.time, r.dx[agent], label=r.name)
        if float(max(r.time[-1] for r in runs)) >= 2.3:
            ax.errorbar(
                [2.3],
                [FIGURE_AT_2_3_S[agent]],
                yerr=[FIGURE_UNCERTAINTY],
                fmt="ko",
                label="tutorial's figure",
            )
        ax.set_ylabel(f"{agent} tip dx [m]")
        ax.grid(True)
    axes[0].legend()
    axes[1].set_xlabel("time [s]")
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m gymprecice_tutorials.two_flaps.validate``: the comparison, printed."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--end-time", type=float, default=2.5, help="seconds of flow")
    parser.add_argument("--cases", default="packaged,fast", help="comma-separated: packaged, fast")
    parser.add_argument("--run-root", type=Path, default=Path("gymprecice-runs/two-flaps"))
    parser.add_argument("--csv", type=Path, default=None, help="write the time series here")
    parser.add_argument("--plot", type=Path, default=None, help="draw the time series here")
    args = parser.parse_args(argv)
    builders: dict[str, Any] = {"packaged": packaged_case_files, "fast": fast_case_files}
    names = [n.strip() for n in args.cases.split(",") if n.strip()]
    unknown = [n for n in names if n not in builders]
    if unknown or not names:
        parser.error(f"--cases: unknown {unknown}; use packaged and/or fast")
    runs = []
    for name in names:
        runs.append(
            run_uncontrolled(name, builders[name](args.end_time), args.end_time, args.run_root)
        )
        print(f"{name}: done in {runs[-1].wall_s:.1f} s", flush=True)
    print(report(runs))
    if args.csv:
        _write_csv(runs, args.csv)
    if args.plot:
        _plot(runs, args.plot)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
