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
* ``summary.json``: per-episode return and the mean of each metric (``mean_Cd``, ...),
  for the cylinders also the mean Cd and mean |Cl| over every solver step
  (``series_mean_Cd``, ``series_mean_abs_Cl``: what a drag-reduction claim is stated in;
  the per-action means differ where the reward averages over a window longer than an
  action), and over the episodes the mean and standard deviation of each
  (``over_episodes``) and, with ``--baseline RUN``, the % change of each mean against
  that run's;
* ``manifest.json``.

The controllers: ``evaluate`` is a trained PPO policy, deterministic by default (the mean
action: what one would deploy), over a horizon longer than the training episodes (10 s
by default against 2 s) to show that the control holds; ``baseline`` is the uncontrolled
flow (zero action: jets closed, cylinder at rest) that a controller is judged against;
``open-loop`` is a sinusoid, the classic forcing a learned controller should beat;
``feedback`` a classical feedback law (:mod:`gymprecice_tutorials.feedback`).

A controller is ``controller(observation, time) -> action``; one with a ``reset()``
method has it called at every episode's start, one with ``observe(info)`` sees every
step's ``info`` (how a feedback law measures its signal). With ``--all-starts`` the
commands run one episode from each held-out start of the env
(:mod:`gymprecice_tutorials.starts`), episode k from held-out start k whatever the seed;
without it each episode's start is drawn from the held-out split by its seed, as before
(the documented results were made that way).

``evaluate --policy`` names the policy: a training directory or model file, a policy
shipped with the package by name, or ``shipped`` (the one shipped for the env). The env
is built with the action bound the policy was trained with, also on another env (a
transfer, said in one line); see :mod:`gymprecice_tutorials.shipped_policies`.
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

from gymprecice_tutorials.environments import DragFloor, TutorialEnv, find_environment
from gymprecice_tutorials.envs import (
    load_model,
    load_normalizer,
    make_env_checked,
    vecnormalize_path,
)
from gymprecice_tutorials.feedback import FeedbackController, FeedbackLaw, load_law
from gymprecice_tutorials.manifest import file_sha256, read_manifest, write_manifest
from gymprecice_tutorials.requirements import require_solvers
from gymprecice_tutorials.shipped_policies import (
    Policy,
    PolicyError,
    check_policy_env,
    policy_env_kwargs,
    resolve_policy,
    shipped_policies,
)
from gymprecice_tutorials.starts import (
    NoHeldOutStarts,
    held_out_starts,
    require_held_out_starts,
    start_options,
)
from gymprecice_tutorials.train import build_env_kwargs, default_out
from gymprecice_tutorials.wrapping import WrapError, wrap_spec

__all__ = [
    "change_against",
    "over_episodes",
    "rollout",
    "rollout_command",
    "sine_controller",
    "zero_controller",
]

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
    space: gym.Space,
    amplitude: float,
    frequency: float,
    phase: float = 0.0,
    centre: float = 0.5,
) -> Controller:
    """``centre + amplitude * half_range * sin(2 pi f t + phase)`` on every action dimension,
    clipped to the box; ``centre`` is a fraction of the box (0.5: its middle)."""
    if not isinstance(space, gym.spaces.Box):
        raise TypeError(f"open-loop needs a Box action space, got {space}")
    centre = space.low + centre * (space.high - space.low)
    half = (space.high - space.low) / 2.0

    def act(obs: Any, t: float) -> np.ndarray:
        value = centre + amplitude * half * math.sin(2.0 * math.pi * frequency * t + phase)
        return np.clip(value, space.low, space.high).astype(space.dtype)

    return act


def law_point(
    env_info: TutorialEnv, text: str | None
) -> tuple[FeedbackLaw, dict[str, float]] | None:
    """``gymprecice feedback --law "kp=3;ki=50;kd=1"``: the env's own feedback law and the
    one point of it to run (``None``: the env's feedback is a signal fed back). Checked
    before any env is built; a ``ValueError`` says what is missing."""
    if env_info.feedback_law is None:
        if text:
            raise ValueError(
                f"{env_info.name} has no feedback law of its own for --law; its classical "
                "feedback is a signal fed back (--signal, --gain, --delay)"
            )
        return None
    law = load_law(env_info.feedback_law)
    example = law.grid_text({n: [v[0]] for n, v in law.default_grid().items()})
    if not text:
        raise ValueError(
            f"{env_info.name}'s classical feedback is its {law.name} law ({law.summary}); "
            f'pass --law with one value of each parameter, e.g. --law "{example}" '
            f"(`gymprecice sweep {env_info.name}` tunes it)"
        )
    grid = law.parse_grid(text, "--law")
    several = [n for n in law.parameters if len(grid[n]) != 1]
    if several:
        raise ValueError(
            f"--law runs one {law.name} controller: give {', '.join(several)} one value "
            f'each, e.g. --law "{example}" (`gymprecice sweep` tunes a grid)'
        )
    (point,) = law.points(grid)
    return law, point


def rollout(
    env: gym.Env,
    controller: Controller,
    out: Path,
    *,
    episodes: int = 1,
    seed: int = 0,
    every_start: bool = False,
    drag_floor: DragFloor | None = None,
) -> dict[str, Any]:
    """Run ``episodes`` whole episodes and write history, coefficients and summary.

    ``every_start``: episode k runs the env's held-out start k (mod their number), the
    same for every controller and seed; otherwise the held-out split draws each
    episode's start from its seed (``seed + k``). ``drag_floor``: each episode's summary
    also gives its settled mean drag and the fractions of the floor it reaches.
    """
    out.mkdir(parents=True, exist_ok=True)
    history_rows: list[dict[str, Any]] = []
    coefficient_rows: list[tuple[int, float, float, float]] = []
    summaries = []
    starts = held_out_starts(env) if every_start else ()
    for episode in range(episodes):
        options = start_options(episode, len(starts))
        obs, info = env.reset(seed=seed + episode, options=options)
        if hasattr(controller, "reset"):
            controller.reset()
        first_row, first_coefficient = len(history_rows), len(coefficient_rows)
        t = t0 = float(info.get("time", 0.0))
        total, step = 0.0, 0
        while True:
            action = controller(obs, t)
            obs, reward, terminated, truncated, info = env.step(action)
            if hasattr(controller, "observe"):
                controller.observe(info)
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
        rows = history_rows[first_row:]
        metrics = dict.fromkeys(
            name
            for r in rows
            for name in r
            if name not in _NOT_METRICS and not name.startswith("action_")
        )
        summary_row: dict[str, Any] = {
            "episode": episode,
            "steps": step,
            "return": total,
            "end_time": t,
        }
        if starts:
            summary_row["start"] = options["start"]
            summary_row["start_label"] = starts[options["start"]]
        summary_row.update(
            {f"mean_{name}": _nanmean([r.get(name, math.nan) for r in rows]) for name in metrics}
        )
        summary_row.update(series_means([r[2:] for r in coefficient_rows[first_coefficient:]]))
        if drag_floor is not None:
            summary_row.update(floor_metrics(coefficient_rows[first_coefficient:], t0, drag_floor))
        summaries.append(summary_row)
    _write_csv(out / "history.csv", history_rows)
    with (out / "coefficients.csv").open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["episode", "time", "Cd", "Cl"])
        writer.writerows(coefficient_rows)
    summary = {
        "episodes": summaries,
        "mean_return": float(np.mean([s["return"] for s in summaries])),
        "over_episodes": over_episodes(summaries),
    }
    (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    return summary


def episodes_by_start(summary: dict[str, Any]) -> list[dict[str, Any]]:
    """A summary's episodes in held-out start order (episode order without starts)."""
    return sorted(summary["episodes"], key=lambda e: int(e.get("start", e["episode"])))


def series_means(coefficients: list[tuple[float, float]]) -> dict[str, float]:
    """Mean Cd and mean |Cl| over an episode's solver steps (none without coefficients)."""
    if not coefficients:
        return {}
    cd, cl = np.asarray(coefficients, dtype=float).T
    return {"series_mean_Cd": float(cd.mean()), "series_mean_abs_Cl": float(np.abs(cl).mean())}


def floor_metrics(
    coefficients: list[tuple[int, float, float, float]], t0: float, floor: DragFloor
) -> dict[str, float]:
    """The settled mean drag (from ``t0 + settle_time`` on) and the fractions of the floor
    that the whole episode's and the settled mean drag reach (none without coefficients)."""
    if not coefficients:
        return {}
    _, time, cd, _ = np.asarray(coefficients, dtype=float).T
    out = {"floor_fraction": floor.fraction(float(cd.mean()))}
    settled = cd[time >= t0 + floor.settle_time - 1e-9]
    if settled.size:
        out["series_settled_mean_Cd"] = float(settled.mean())
        out["settled_floor_fraction"] = floor.fraction(float(settled.mean()))
    return out


def over_episodes(episodes: list[dict[str, Any]]) -> dict[str, dict[str, float | int]]:
    """Mean, standard deviation (``ddof=0``) and count over episodes of each scalar."""
    keys = [
        k for k in episodes[0] if k not in ("episode", "steps", "end_time", "start", "start_label")
    ]
    out: dict[str, dict[str, float | int]] = {}
    for key in keys:
        values = np.array([e[key] for e in episodes if e.get(key) is not None], dtype=float)
        values = values[np.isfinite(values)]
        if values.size:
            out[key] = {
                "mean": float(values.mean()),
                "std": float(values.std()),
                "n": int(values.size),
            }
    return out


def change_against(summary: dict[str, Any], baseline: dict[str, Any]) -> dict[str, float]:
    """% change of each mean over episodes against a baseline summary's (same keys)."""
    ours, theirs = summary["over_episodes"], baseline.get("over_episodes")
    if theirs is None:  # a summary written before over_episodes existed
        theirs = over_episodes(baseline["episodes"])
    out = {}
    for key, stats in ours.items():
        ref = theirs.get(key, {}).get("mean")
        if ref:
            out[key] = 100.0 * (stats["mean"] - ref) / abs(ref)
    return out


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


def _policy(args: argparse.Namespace, env: TutorialEnv) -> Policy:
    """The policy to evaluate (``--policy``/``--model``, default ``runs/<env>/train``)."""
    spec = getattr(args, "policy", None)
    try:
        policy = resolve_policy(spec if spec is not None else default_out(env, "train"), env)
    except PolicyError as exc:
        hint = ""
        if spec is None:
            names = ", ".join(shipped_policies()) or "none yet"
            hint = (
                f"; train one first (`gymprecice train {env.name}`) or pass --policy "
                f"NAME|PATH (shipped policies: {names})"
            )
        raise SystemExit(f"gymprecice evaluate: {exc}{hint}") from None
    for note in policy.notes:
        print(f"gymprecice evaluate: {note}")
    return policy


def _read_baseline(path: Path) -> dict[str, Any]:
    try:
        return json.loads((path / "summary.json").read_text())
    except (OSError, ValueError) as exc:
        raise SystemExit(
            f"gymprecice: --baseline {path}: no readable summary.json ({exc}); run "
            f"`gymprecice baseline ENV --out {path}` first"
        ) from None


#: What the one-line report shows: (summary key, label, % change against a baseline?).
#: The cylinders' drag and lift over every solver step where recorded, else the per-action
#: metrics. No % for the return or the signed lift: both are about zero uncontrolled (the
#: reward offset is the uncontrolled drag), so a relative change of them says nothing.
_REPORTED = {
    "series": (
        ("return", "return", False),
        ("series_mean_Cd", "mean Cd", True),
        ("series_mean_abs_Cl", "mean |Cl|", True),
        ("floor_fraction", "fraction of the drag floor", False),
        ("settled_floor_fraction", "settled", False),
    ),
    "actions": (
        ("return", "return", False),
        ("mean_Cd", "mean Cd", True),
        ("mean_Cl", "mean Cl", False),
    ),
}


def _report(command: str, summary: dict[str, Any], out: Path) -> str:
    """One line: mean ± std over the episodes of return, Cd and |Cl| (and % change if known)."""
    stats = summary["over_episodes"]
    source = "series" if "series_mean_Cd" in stats else "actions"
    parts = []
    for key, label, relative in _REPORTED[source]:
        if key in stats:
            part = f"{label} {stats[key]['mean']:.4f} ± {stats[key]['std']:.4f}"
            change = summary.get("change_percent", {}).get(key)
            if relative and change is not None:
                part += f" ({change:+.2f} % against the baseline)"
            parts.append(part)
    over = "over every solver step, " if source == "series" else ""
    return (
        f"gymprecice {command}: {len(summary['episodes'])} episode(s), "
        f"{', '.join(parts)} ({over}mean ± std over episodes); results in {out}"
    )


def rollout_command(command: str, args: argparse.Namespace) -> int:
    """``gymprecice evaluate`` / ``baseline`` / ``open-loop`` / ``feedback``."""
    try:
        env_info = find_environment(args.env)
    except KeyError as exc:
        print(f"gymprecice {command}: {exc.args[0]}", file=sys.stderr)
        return 2
    out = (args.out or default_out(env_info, command)).resolve()
    kwargs = build_env_kwargs(args, env_info, out)
    if command == "baseline":  # where the action cannot say "uncontrolled", a kwarg does
        kwargs = {**dict(env_info.baseline_kwargs), **kwargs}
    baseline = _read_baseline(args.baseline) if getattr(args, "baseline", None) else None
    policy = _policy(args, env_info) if command == "evaluate" else None
    applied: dict[str, Any] = {}
    if policy is not None:
        # the policy acts in [-1, 1]: the env must have the bound it was trained with
        try:
            applied, lines = policy_env_kwargs(policy, env_info, args.env_kwargs or {})
        except PolicyError as exc:
            print(f"gymprecice evaluate: {exc}", file=sys.stderr)
            return 2
        for line in lines:
            print(f"gymprecice evaluate: {line}")
        kwargs.update(applied)
    # what was typed is checked before the machine: a bad --law is the user's to fix anywhere
    try:
        own_law = law_point(env_info, getattr(args, "law", None)) if command == "feedback" else None
    except ValueError as exc:
        print(f"gymprecice {command}: {exc}", file=sys.stderr)
        return 2
    if command == "feedback" and own_law is None and not (args.signal or env_info.feedback_signal):
        print(
            f"gymprecice feedback: {env_info.name} has no default signal; pass --signal "
            "NAME (one of the metrics its steps report in info['metrics'])",
            file=sys.stderr,
        )
        return 2
    if not args.double:
        status = require_solvers(env_info, command, verbose=args.require_solvers)
        if status:
            return status
    # The policy acts in [-1, 1] (training rescales); the fixed controllers act in the
    # env's own units, so that "zero" means jets closed.
    # the robustness wrappers' noise is seeded by each episode's reset seed
    try:
        robustness = wrap_spec(getattr(args, "wrap", []))
    except WrapError as exc:
        print(f"gymprecice {command}: {exc}", file=sys.stderr)
        return 2
    env = make_env_checked(
        env_info.name,
        env_info.env_id,
        0,
        kwargs,
        rescale=command == "evaluate",
        robustness=robustness,
    )
    episodes = args.episodes
    if getattr(args, "all_starts", False):
        try:
            episodes = len(require_held_out_starts(env, env_info))
        except NoHeldOutStarts as exc:
            env.close()
            print(f"gymprecice {command}: {exc}", file=sys.stderr)
            return 2
    settings: dict[str, Any] = {
        "robustness": robustness,
        "env_id": env_info.env_id,
        "env_kwargs": kwargs,
        "episodes": episodes,
        "held_out_starts": list(held_out_starts(env))
        if getattr(args, "all_starts", False)
        else None,
        "double": args.double,
    }
    try:
        if command == "evaluate":
            assert policy is not None
            model_path = policy.model
            model = load_model(model_path)
            try:
                check_policy_env(policy, model, env, env_info.name, applied)
            except PolicyError as exc:
                print(f"gymprecice evaluate: {exc}", file=sys.stderr)
                return 2
            normalizer = load_normalizer(model_path)
            deterministic = not args.stochastic

            def controller(obs: Any, t: float) -> Any:
                if normalizer is not None:
                    obs = normalizer.normalize_obs(obs)
                action, _ = model.predict(obs, deterministic=deterministic)
                return action

            settings.update(
                {
                    "model": str(model_path.resolve()),
                    "policy": policy.describe(),
                    "model_sha256": file_sha256(model_path),
                    "normalization": str(vecnormalize_path(model_path)) if normalizer else None,
                    "deterministic": deterministic,
                }
            )
        elif command == "baseline":
            controller = zero_controller(env.action_space)
        elif command == "feedback" and own_law is not None:
            law, point = own_law
            try:
                controller = law.build(env.action_space, point)
            except ValueError as exc:
                print(f"gymprecice feedback: {exc}", file=sys.stderr)
                return 2
            settings.update({"law": env_info.feedback_law, **point})
        elif command == "feedback":
            signal = str(args.signal or env_info.feedback_signal)
            try:
                feedback = FeedbackController(
                    env.action_space, signal, args.gain, args.delay, args.centre
                )
            except (TypeError, ValueError) as exc:
                print(f"gymprecice feedback: {exc}", file=sys.stderr)
                return 2
            controller = feedback
            settings.update(feedback.settings())
        else:
            frequency = args.frequency or env_info.open_loop_frequency
            controller = sine_controller(env.action_space, args.amplitude, frequency, args.phase)
            settings.update(
                {"amplitude": args.amplitude, "frequency": frequency, "phase": args.phase}
            )
        case_dir = getattr(getattr(env.unwrapped, "config", None), "case_dir", None)
        seeds = {"seed": args.seed, "episode_seeds": [args.seed + i for i in range(episodes)]}
        write_manifest(out, command=command, case_dir=case_dir, seeds=seeds, settings=settings)
        summary = rollout(
            env,
            controller,
            out,
            episodes=episodes,
            seed=args.seed,
            every_start=bool(getattr(args, "all_starts", False)),
            drag_floor=env_info.drag_floor,
        )
        if baseline is not None:
            summary["baseline"] = str(args.baseline.resolve())
            summary["change_percent"] = change_against(summary, baseline)
            (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
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
    print(_report(command, summary, out))
    return 0
