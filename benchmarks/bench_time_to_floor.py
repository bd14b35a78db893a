"""Benchmark: the wall-clock from the typed training command to a controlled jet cylinder.

For each training recipe and seed it runs the command a user types (``gymprecice train
jet-cylinder-fast ...``, timed from its own start), then ``gymprecice time-to-floor`` on
its checkpoints: the first checkpoint whose deterministic evaluation from both held-out
starts takes 90 % and 95 % of the drag floor's drop once settled. It prints, side by side,
per recipe the median over the seeds with a 95 % bootstrap interval, and how many seeds
got there within the recipe's training.

Everything resumes: a seed already trained is kept, a seed cut short resumes from its
newest checkpoint (its clock then includes the restart), an evaluation already made is
reused. ``--from-benchmark DIR`` (repeatable) adds the seeds that a ``gymprecice benchmark`` run
trained (``DIR/train/<algo>``, every algorithm), timed from each seed's own training
start, so one benchmark serves both the table and this figure.

Run: ``python benchmarks/bench_time_to_floor.py --recipes ppo --seeds 5`` (needs preCICE
and OpenFOAM with the adapter; a recipe's seed costs about a quarter of an hour of both
cores). Prints figures; not a test.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import time
from pathlib import Path

#: name -> (what it changes, `gymprecice train` flags). Every recipe trains JetCylinderFast-v0
#: with 2 s episodes on 2 environments and checkpoints every 800 actions (unless it says).
RECIPES: dict[str, tuple[str, list[str]]] = {
    "ppo": (
        "the benchmark's: bash scripts/train.sh's PPO (512 x 512, 80-action rollouts) "
        "stopped at 4,000 actions",
        ["--hyperparams", "scripts/ppo-fast.yml", "--timesteps", "4000"],
    ),
    "ppo-8k": (
        "bash scripts/train.sh as it is: the same PPO for 8,000 actions",
        ["--hyperparams", "scripts/ppo-fast.yml", "--timesteps", "8000"],
    ),
    "ppo-small-net": (
        "the same with a 64 x 64 network",
        ["--hyperparams", "scripts/ppo-fast.yml", "--timesteps", "4000", "--net", "64,64"],
    ),
    "ppo-half-rollouts": (
        "the same with 40-action rollouts (twice the updates per action)",
        ["--hyperparams", "scripts/ppo-fast.yml", "--timesteps", "4000", "--n-steps", "40"],
    ),
    "sac": (
        "SAC with SB3's settings, 256 x 256, one gradient step per batch of 2 actions",
        ["--algo", "sac", "--timesteps", "4000"],
    ),
    "sac-fast": (
        "the benchmark's SAC: scripts/sac-fast.yml (update-to-data ratio 2, discount 0.98), "
        "4,000 actions",
        ["--algo", "sac", "--hyperparams", "scripts/sac-fast.yml", "--timesteps", "4000"],
    ),
    "sac-small-net": (
        "the benchmark's SAC with a 64 x 64 network (its updates about twice as fast, the "
        "training 1.5 % faster), checkpoints every 400 actions",
        [
            "--algo",
            "sac",
            "--hyperparams",
            "scripts/sac-fast.yml",
            "--net",
            "64,64",
            "--timesteps",
            "4000",
            "--checkpoint-every",
            "400",
        ],
    ),
    "sac-utd1": (
        "the benchmark's SAC with 2 gradient steps per batch (update-to-data ratio 1, the "
        "learner's cost halved)",
        [
            "--algo",
            "sac",
            "--hyperparams",
            "benchmarks/hyperparams/sac-utd1.yml",
            "--timesteps",
            "4000",
        ],
    ),
    "sac-utd4": (
        "the benchmark's SAC with 8 gradient steps per batch (update-to-data ratio 4, the "
        "learner's cost doubled)",
        [
            "--algo",
            "sac",
            "--hyperparams",
            "benchmarks/hyperparams/sac-utd4.yml",
            "--timesteps",
            "4000",
        ],
    ),
    "sac-overlap": (
        "the benchmark's SAC with its updates while the solvers compute and one learner "
        "thread (scripts/sac-overlap.yml)",
        ["--algo", "sac", "--hyperparams", "scripts/sac-overlap.yml", "--timesteps", "4000"],
    ),
    "td3-fast": (
        "TD3 with sac-fast's settings (scripts/td3-fast.yml: update-to-data ratio 2, Gaussian "
        "exploration noise 0.1)",
        ["--algo", "td3", "--hyperparams", "scripts/td3-fast.yml", "--timesteps", "4000"],
    ),
    "ppo-model-ensemble": (
        "the benchmark's PPO with drlFoam's model ensemble: after each CFD update, up to 4 "
        "on trajectories 5 learned models predict (scripts/ppo-model-ensemble.yml)",
        ["--hyperparams", "scripts/ppo-model-ensemble.yml", "--timesteps", "4000"],
    ),
}
COMMON = [
    "--require-solvers",
    "--n-envs",
    "2",
    "--normalize",
    "--episode-time",
    "2",
    "--checkpoint-every",
    "800",
    "--keep-checkpoints",
    "20",
    "--no-progress-bar",
]
GYMPRECICE = [sys.executable, "-m", "gymprecice"]


def _trained(run: Path) -> bool:
    try:
        result = json.loads((run / "manifest.json").read_text()).get("result") or {}
    except (OSError, ValueError):
        return False
    return (run / "model.zip").is_file() and not result.get("interrupted")


def train(recipe: str, seed: int, run: Path) -> None:
    if _trained(run):
        print(f"{recipe} seed {seed}: trained already, kept", flush=True)
        return
    flags = RECIPES[recipe][1]
    command = [*GYMPRECICE, "train", "jet-cylinder-fast", *COMMON, *flags]
    command += ["--seed", str(seed), "--out", str(run)]
    started = time.monotonic()
    subprocess.run(command, check=True)
    print(f"{recipe} seed {seed}: trained in {time.monotonic() - started:.0f} s", flush=True)


def scan(runs: list[Path], out: Path, workers: int) -> dict:
    command = [*GYMPRECICE, "time-to-floor", *map(str, runs), "--workers", str(workers)]
    subprocess.run([*command, "--out", str(out)], check=True)
    return json.loads((out / "time_to_floor.json").read_text())["summary"]


def _clock(seconds: float) -> str:
    if seconds is None or not math.isfinite(seconds):
        return "not reached"
    return f"{seconds / 60:.1f} min"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--recipes", default="ppo", help=f"comma-separated: {', '.join(RECIPES)}")
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--out", type=Path, default=Path("runs/bench-time-to-floor"))
    parser.add_argument(
        "--from-benchmark",
        type=Path,
        action="append",
        default=[],
        metavar="DIR",
        help="scan the seeds of this gymprecice benchmark's --out too (repeatable)",
    )
    parser.add_argument("--workers", type=int, default=2, help="evaluations at once")
    args = parser.parse_args()
    names = [r for r in args.recipes.split(",") if r]
    unknown = [r for r in names if r not in RECIPES]
    if unknown:
        parser.error(f"unknown recipe(s) {', '.join(unknown)}; choose from {', '.join(RECIPES)}")
    results: dict[str, dict] = {}
    for bench in args.from_benchmark:
        settings = json.loads((bench / "benchmark.json").read_text())
        for algo in settings["algos"]:
            runs = sorted((bench / "train" / algo).glob("seed_*"))
            label = f"benchmark: {algo.upper()}, {settings['timesteps']:,} actions ({bench.name})"
            results[label] = scan(
                runs, args.out / "from-benchmark" / bench.name / algo, args.workers
            )
    for recipe in names:
        runs = [args.out / recipe / f"seed_{seed}" for seed in range(args.seeds)]
        for seed, run in enumerate(runs):
            train(recipe, seed, run)
        results[f"{recipe}: {RECIPES[recipe][0]}"] = scan(
            runs, args.out / recipe / "scan", args.workers
        )

    print()
    print(
        "| recipe | seeds | 90 % of the floor: median [95 % CI] | 95 %: median [95 % CI] | seeds reaching 95 % |"
    )
    print("| --- | --- | --- | --- | --- |")
    for label, summary in results.items():
        cells = []
        for fraction in ("0.9", "0.95"):
            s = summary[fraction]
            cells.append(f"{_clock(s['median'])} [{_clock(s['low'])}, {_clock(s['high'])}]")
        reached = sum(math.isfinite(t) for t in summary["0.95"]["seconds"])
        runs = summary["0.95"]["runs"]
        print(f"| {label} | {runs} | {cells[0]} | {cells[1]} | {reached} of {runs} |")


if __name__ == "__main__":
    main()
