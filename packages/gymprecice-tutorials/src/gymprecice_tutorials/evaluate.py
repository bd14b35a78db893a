"""``gymprecice evaluate | baseline | open-loop``: run a controller and record what happens.

All three run whole episodes of one environment with a fixed controller and write the
same files, so ``gymprecice plot`` can put any of them side by side:

* ``history.csv``: one row per action: ``episode, step, start, time, reward``, the
  step's metrics, ``action_0..`` (``start``/``time``: coupling time at the action's start
  and end; metrics: the named scalars an env reports in ``info["metrics"]``, e.g. the
  cylinders' ``Cd``/``Cl`` averages the reward used, or the flap's tip displacement;
  actions in the env's own units);
* ``coefficients.csv``: every solver step's ``episode, time, Cd, Cl`` (the time series of
  the cylinder envs; header only for envs without force coefficients);
* ``summary.json``: per-episode return and the mean of each metric (``mean_Cd``, ...);
* ``manifest.json``.

The controllers: ``evaluate`` is a trained PPO policy, deterministic by default (the mean
action: what one would deploy), over a horizon longer than the training episodes (10 s
by default against 2 s) to show that the control holds; ``baseline`` is the uncontrolled
flow (zero action: jets closed, cylinder at rest) that a controller is judged against;
``open-loop`` is a sinusoid, the classic forcing a learned controller should beat.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from gymprecice_tutorials.manifest import read_manifest, write_manifest
from gymprecice_tutorials.plugin import TutorialEnv, find_environment
from gymprecice_tutorials.train import (
    build_env_kwargs,
    default_out,
    make_env,
    require_solvers,
)

__all__ = ["rollout", "rollout_command", "sine_controller", "zero_controller"]

#: ``controller(observation, time) -> action`` (in the env's own action space)
Controller = Callable[[Any, float], Any]


def zero_controller(space: gym.Space) -> Controller:
    """The uncontrolled flow: action zero (clipped into the box if zero lies outside)."""
    if isinstance(space, gym.spaces.Box):
        action = np.clip(np.zeros(space.shape), space.low, space.high).astype(space.dtype)
    else:
        raise TypeError(f"baseline needs a Box action space, got {space}")
    return lambda obs, t: action


def sine_controller(
    space: gym.Space, amplitude: float, frequency: float, phase: float = 0.0
) -> Controller:
    """``centre + amplitude * half_range * sin(2 pi f t + phase)`` on every action dimension."""
    if not isinstance(space, gym.spaces.Box):
        raise TypeError(f"open-loop needs a Box action space, got {space}")
    centre = (space.high + space.low) / 2.0
    half = (space.high - space.low) / 2.0

    def act(obs: Any, t: float) -> np.ndarray:
        value = centre + amplitude * half * math.sin(2.0 * math.pi * frequency * t + phase)
        return np.clip(value, space.low, space.high).astype(space.dtype)

    return act


def rollout(
    env: gym.Env,
    controller: Controller,
    out: Path,
    *,
    episodes: int = 1,
    seed: int = 0,
) -> dict[str, Any]:
    """Run ``episodes`` whole episodes and write history, coefficients and summary."""
    out.mkdir(parents=True, exist_ok=True)
    history_rows: list[dict[str, Any]] = []
    coefficient_rows: list[tuple[int, float, float, float]] = []
    summaries = []
    for episode in range(episodes):
        obs, info = env.reset(seed=seed + episode)
        t = float(info.get("time", 0.0))
        total, step = 0.0, 0
        while True:
            action = controller(obs, t)
            obs, reward, terminated, truncated, info = env.step(action)
            step += 1
            total += float(reward)
            start, t = t, float(info.get("time", t))
            physical = info.get("action", np.asarray(action, dtype=float).reshape(-1).tolist())
            row: dict[str, Any] = {
                "episode": episode,
                "step": step,
                "start": start,
                "time": t,
                "reward": float(reward),
            }
            row.update({name: float(v) for name, v in info.get("metrics", {}).items()})
            row.update({f"action_{i}": float(a) for i, a in enumerate(physical)})
            history_rows.append(row)
            for time_, cd, cl in np.asarray(info.get("coefficients", np.zeros((0, 3)))):
                coefficient_rows.append((episode, float(time_), float(cd), float(cl)))
            if terminated or truncated:
                break
        rows = [r for r in history_rows if r["episode"] == episode]
        metrics = dict.fromkeys(
            name
            for r in rows
            for name in r
            if name not in _NOT_METRICS and not name.startswith("action_")
        )
        summary_row = {"episode": episode, "steps": step, "return": total, "end_time": t}
        summary_row.update(
            {f"mean_{name}": _nanmean([r.get(name, math.nan) for r in rows]) for name in metrics}
        )
        summaries.append(summary_row)
    _write_csv(out / "history.csv", history_rows)
    with (out / "coefficients.csv").open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["episode", "time", "Cd", "Cl"])
        writer.writerows(coefficient_rows)
    summary = {
        "episodes": summaries,
        "mean_return": float(np.mean([s["return"] for s in summaries])),
    }
    (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    return summary


_NOT_METRICS = {"episode", "step", "start", "time", "reward"}


def _nanmean(values: list[Any]) -> float | None:
    array = np.asarray(values, dtype=float)
    if not array.size or np.all(np.isnan(array)):
        return None
    return float(np.nanmean(array))


def _write_csv(path: Path, rows: list[dict[str, Any]]) -> None:
    fields: list[str] = []
    for row in rows:
        fields += [k for k in row if k not in fields]
    with path.open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=fields or ["episode"])
        writer.writeheader()
        writer.writerows(rows)


def _model_path(args: argparse.Namespace, env: TutorialEnv) -> Path:
    path = args.model or default_out(env, "train")
    if path.is_dir():
        path = path / "model.zip"
    if not path.is_file():
        raise SystemExit(
            f"gymprecice evaluate: no trained model at {path}; train one first "
            f"(`gymprecice train {env.name}`) or pass --model"
        )
    return path


def rollout_command(command: str, args: argparse.Namespace) -> int:
    """``gymprecice evaluate`` / ``baseline`` / ``open-loop``."""
    try:
        env_info = find_environment(args.env)
    except KeyError as exc:
        print(f"gymprecice {command}: {exc.args[0]}", file=sys.stderr)
        return 2
    if args.require_solvers and not args.double:
        status = require_solvers(env_info, command)
        if status:
            return status
    model_path = _model_path(args, env_info) if command == "evaluate" else None
    out = (args.out or default_out(env_info, command)).resolve()
    kwargs = build_env_kwargs(args, env_info, out)
    # The policy acts in [-1, 1] (training rescales); the fixed controllers act in the
    # env's own units, so that "zero" means jets closed.
    env = make_env(env_info.env_id, 0, kwargs, rescale=command == "evaluate")
    settings: dict[str, Any] = {
        "env_id": env_info.env_id,
        "env_kwargs": kwargs,
        "episodes": args.episodes,
        "double": args.double,
    }
    try:
        if command == "evaluate":
            from stable_baselines3 import PPO

            assert model_path is not None
            model = PPO.load(model_path, device="cpu")
            deterministic = not args.stochastic

            def controller(obs: Any, t: float) -> Any:
                action, _ = model.predict(obs, deterministic=deterministic)
                return action

            settings.update({"model": str(model_path.resolve()), "deterministic": deterministic})
        elif command == "baseline":
            controller = zero_controller(env.action_space)
        else:
            frequency = args.frequency or env_info.open_loop_frequency
            controller = sine_controller(env.action_space, args.amplitude, frequency, args.phase)
            settings.update(
                {"amplitude": args.amplitude, "frequency": frequency, "phase": args.phase}
            )
        case_dir = getattr(getattr(env.unwrapped, "config", None), "case_dir", None)
        seeds = {"seed": args.seed, "episode_seeds": [args.seed + i for i in range(args.episodes)]}
        write_manifest(out, command=command, case_dir=case_dir, seeds=seeds, settings=settings)
        summary = rollout(env, controller, out, episodes=args.episodes, seed=args.seed)
    finally:
        env.close()
    write_manifest(
        out,
        command=command,
        case_dir=case_dir,
        seeds=seeds,
        settings=settings,
        solvers=read_manifest(out)["solvers"],
        extra={"result": summary},
    )
    last = summary["episodes"][-1]
    cd = f", mean Cd {last['mean_Cd']:.4f}" if last.get("mean_Cd") is not None else ""
    print(
        f"gymprecice {command}: {len(summary['episodes'])} episode(s), return "
        f"{summary['mean_return']:.4f}{cd}; results in {out}"
    )
    return 0
