"""A robustness study: a policy's drag and lift change against sensor-noise level.

Runs, for each noise level, ``gymprecice evaluate ENV --policy POLICY --baseline RUN
--wrap sensor_noise:std=LEVEL,mode=relative`` (level 0 without the wrapper), once the
uncontrolled baseline is there, then draws the mean Cd and mean |Cl| change against the
baseline as a figure. Every run is a directory under ``--out``; a run that already has
its ``summary.json`` is reused, so the study resumes where it stopped.

    python scripts/robustness_study.py                      # the shipped jet policy
    python scripts/robustness_study.py --levels 0 0.1 0.3 --figure noise.png

The noise of each episode is drawn from its reset seed (``--seed``, default 0), so the
same command gives the same figure.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

DEFAULT_LEVELS = (0.0, 0.02, 0.05, 0.1, 0.2, 0.5)


def _gymprecice(*args: str) -> None:
    command = [sys.executable, "-m", "gymprecice", *args]
    print("$", " ".join(command[2:]), flush=True)
    subprocess.run(command, check=True)


def _summary(run: Path) -> dict | None:
    path = run / "summary.json"
    return json.loads(path.read_text()) if path.is_file() else None


def study(env: str, policy: str, levels: list[float], out: Path, seed: int) -> list[dict]:
    """Run what is missing; return one row per level: std, Cd and |Cl| change in %."""
    baseline = out / "baseline"
    if _summary(baseline) is None:
        _gymprecice("baseline", env, "--seed", str(seed), "--out", str(baseline))
    rows = []
    for level in levels:
        run = out / f"sensor-noise-{level:g}"
        if _summary(run) is None:
            wrap = [] if level == 0 else ["--wrap", f"sensor_noise:std={level:g},mode=relative"]
            args = ["evaluate", env, "--policy", policy, "--baseline", str(baseline)]
            _gymprecice(*args, "--seed", str(seed), *wrap, "--out", str(run))
        change = _summary(run)["change_percent"]  # type: ignore[index]
        rows.append(
            {
                "std": level,
                "mean_Cd_change_percent": change["series_mean_Cd"],
                "mean_abs_Cl_change_percent": change["series_mean_abs_Cl"],
            }
        )
    return rows


def plot(rows: list[dict], figure: Path, title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    levels = [row["std"] for row in rows]
    fig, (cd, cl) = plt.subplots(1, 2, figsize=(8.0, 3.4))
    cd.plot(levels, [row["mean_Cd_change_percent"] for row in rows], "o-")
    cd.set_ylabel("mean Cd change vs uncontrolled (%)")
    cl.plot(levels, [row["mean_abs_Cl_change_percent"] for row in rows], "s-", color="tab:orange")
    cl.set_ylabel("mean |Cl| change vs uncontrolled (%)")
    for ax in (cd, cl):
        ax.set_xlabel("sensor noise (std relative to each probe)")
        ax.set_ylim(top=0.0)
        ax.grid(alpha=0.3)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(figure, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", default="jet-cylinder-fast")
    parser.add_argument("--policy", default="shipped")
    parser.add_argument("--levels", type=float, nargs="+", default=list(DEFAULT_LEVELS))
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=Path("runs/robustness-sensor-noise"))
    parser.add_argument("--figure", type=Path, default=None, help="default: <out>/figure.png")
    args = parser.parse_args(argv)
    if any(level < 0 for level in args.levels):
        parser.error("--levels must be noise standard deviations >= 0")
    rows = study(args.env, args.policy, args.levels, args.out, args.seed)
    (args.out / "study.json").write_text(json.dumps(rows, indent=2) + "\n")
    print(f"{'noise std':>10} {'Cd change %':>12} {'|Cl| change %':>14}")
    for row in rows:
        print(
            f"{row['std']:>10g} {row['mean_Cd_change_percent']:>12.2f} "
            f"{row['mean_abs_Cl_change_percent']:>14.2f}"
        )
    figure = args.figure or args.out / "figure.png"
    plot(rows, figure, f"{args.env}, policy {args.policy}: one held-out start, 10 s")
    print(f"figure: {figure}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
