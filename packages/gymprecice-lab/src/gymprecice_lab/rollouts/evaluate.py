"""``gymprecice evaluate | baseline | open-loop``: run a controller and record what happens.

All three run whole episodes of one environment with a fixed controller and write the
same files, so ``gymprecice plot`` can put any of them side by side:

* ``history.csv``: one row per action: ``episode, step, start, time, reward``, the
  step's metrics, ``action_0..`` (``start``/``time``: coupling time at the action's start
  and end; metrics: the named scalars an env reports in ``info["metrics"]``, e.g. the
  cylinders' ``Cd``/``Cl`` averages the reward used, or the flap's tip displacement;
  actions in the env's own units);
* ``coefficients.csv``: every solver step's ``episode, time`` and the force coefficients
  among the env's ``info["metrics"]`` (the cylinders' ``Cd, Cl``, from each step's
  ``info["coefficients"]`` rows); not written for an env whose metrics have neither;
* ``summary.json``: per-episode return and the mean of each metric the env reports
  (``mean_<name>``: the cylinders' ``mean_Cd``, the flap's ``mean_mean_tip_displacement``,
  the heated plate's ``mean_tracking_error``), for an env with force coefficients (the
  cylinders) also the mean Cd and mean |Cl| over every solver step
  (``series_mean_Cd``, ``series_mean_abs_Cl``: what a drag-reduction claim is stated in;
  the per-action means differ where the reward averages over a window longer than an
  action), and over the episodes the mean and standard deviation of each
  (``over_episodes``) and, with ``--baseline RUN``, the % change of each mean against
  that run's;
* ``manifest.json``.

The controllers: ``evaluate`` is a trained PPO policy, deterministic by default (the mean
action: what one would deploy), over a horizon longer than the training episodes (10 s
by default against 2 s) to show that the control holds; ``baseline`` is the uncontrolled
flow that a controller is judged against (the zero action clipped into the action box,
in the env's own units: jets closed, cylinder at rest; with the card's ``uncontrolled``
env keywords where it declares them); ``open-loop`` is a sinusoid, the classic forcing a
learned controller should beat;
``feedback`` a classical feedback law (:mod:`gymprecice_lab.rollouts.feedback`).

A controller is ``controller(observation, time) -> action``; one with a ``reset()``
method has it called at every episode's start, one with ``observe(info)`` sees every
step's ``info`` (how a feedback law measures its signal). With ``--all-starts`` the
commands run one episode from each held-out start of the env
(:mod:`gymprecice_lab.common.starts`), episode k from held-out start k whatever the seed;
without it each episode's start is drawn from the held-out split by its seed, as before
(the documented results were made that way).

``--video [FILE]`` (any of the four) also writes a video of each episode, MP4 or GIF
(:mod:`gymprecice_lab.rollouts.video`; default ``episode.mp4`` in ``--out``), named in the
summary's episodes.

``evaluate --policy`` names the policy: a training directory or model file, a policy
shipped with the package by name, or ``shipped`` (the one shipped for the env). The env
is built with the action bound the policy was trained with, also on another env (a
transfer, said in one line); see :mod:`gymprecice_lab.policies.shipped` and
:mod:`gymprecice_lab.policies.fitted_env`.
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import json
import math
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from gymprecice.card import FeedbackLaw, Reference, load_object
from gymprecice_lab.common.constructor_kwargs import build_env_kwargs
from gymprecice_lab.common.manifest import file_sha256, read_manifest, write_manifest
from gymprecice_lab.common.registered_env import (
    LabEnv,
    LabEnvError,
    default_frequency,
    default_out,
    find_lab_env,
)
from gymprecice_lab.common.requirements import require_solvers
from gymprecice_lab.common.starts import (
    StartsError,
    evaluation_starts,
    held_out_starts,
    seed_start_label,
    start_options,
)
from gymprecice_lab.common.wrapped_env import (
    load_model,
    load_normalizer,
    make_env_checked,
    vecnormalize_path,
)
from gymprecice_lab.common.wrapping import WrapError, wrap_spec
from gymprecice_lab.policies.fitted_env import check_policy_env, policy_env_kwargs
from gymprecice_lab.policies.policy import Policy, PolicyError
from gymprecice_lab.policies.shipped import resolve_policy, shipped_policies
from gymprecice_lab.rollouts.feedback import FeedbackController
from gymprecice_lab.rollouts.video import (
    DEFAULT_NAME,
    VideoError,
    VideoFile,
    check_renders,
    check_video_path,
    episode_video_path,
)

__all__ = [
    "change_against",
    "coefficient_columns",
    "over_episodes",
    "rollout",
    "rollout_command",
    "sine_controller",
    "zero_controller",
]

#: ``controller(observation, time) -> action`` (in the env's own action space)
Controller = Callable[[Any, float], Any]


def zero_controller(space: gym.Space) -> Controller:
    """The uncontrolled flow: the zero action clipped into the action box (the box's
    nearest bound where zero lies outside it), in the env's own units."""
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


def law_point(env_info: LabEnv, text: str | None) -> tuple[FeedbackLaw, dict[str, float]] | None:
    """``gymprecice feedback --law "kp=3;ki=50;kd=1"``: the env's own feedback law and the
    one point of it to run (``None``: the env's feedback is a signal fed back). Checked
    before any env is built; a ``ValueError`` says what is missing."""
    if env_info.feedback_law is None:
        if text:
            raise ValueError(
                f"{env_info.name} has no feedback law of its own for --law (lab card field "
                "'feedback_law'); its classical feedback is a signal fed back (--signal, "
                "--gain, --delay)"
            )
        return None
    law = load_object(env_info.feedback_law, "feedback_law")
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
    reference: Reference | None = None,
    video: Path | None = None,
) -> dict[str, Any]:
    """Run ``episodes`` whole episodes and write history, coefficients and summary.

    ``every_start``: episode k runs the env's held-out start k (mod their number), the
    same for every controller and seed (an env without held-out starts: its seed
    ``seed + k``, the start labelled so); otherwise the held-out split draws each
    episode's start from its seed (``seed + k``). ``reference`` (the card's, a drag
    floor): each episode's summary also gives its settled mean of the reference's metric
    and the fractions of the floor it reaches. ``video``: each episode's frames (the env
    renders) go to :func:`~gymprecice_lab.rollouts.video.episode_video_path`.
    """
    out.mkdir(parents=True, exist_ok=True)
    history_rows: list[dict[str, Any]] = []
    coefficient_rows: list[tuple[int, float, float, float]] = []
    summaries = []
    starts = held_out_starts(env) if every_start else ()
    seeded = every_start and not starts  # starts are seeds
    for episode in range(episodes):
        options = start_options(episode, len(starts))
        path = episode_video_path(video, episode, episodes) if video is not None else None
        rows, coefficients, summary_row, t0 = _episode(
            env, controller, episode, seed + episode, options, path
        )
        if starts:
            summary_row["start"] = options["start"]
            summary_row["start_label"] = starts[options["start"]]
        elif seeded:
            summary_row["start"] = episode
            summary_row["start_label"] = seed_start_label(seed + episode)
        if path is not None:
            summary_row["video"] = str(path)
        summary_row.update(
            {
                f"mean_{name}": _nanmean([r.get(name, math.nan) for r in rows])
                for name in _metric_names(rows)
            }
        )
        summary_row.update(series_means([c[2:] for c in coefficients]))
        if reference is not None:
            summary_row.update(floor_metrics(coefficients, t0, reference, rows))
        history_rows += rows
        coefficient_rows += coefficients
        summaries.append(summary_row)
    columns = coefficient_columns(_metric_names(history_rows))
    return _write_rollout(out, history_rows, coefficient_rows, summaries, columns)


def _episode(
    env: gym.Env,
    controller: Controller,
    episode: int,
    seed: int,
    options: dict[str, Any],
    video: Path | None = None,
) -> tuple[list[dict[str, Any]], list[tuple[int, float, float, float]], dict[str, Any], float]:
    """Run one whole episode (its frames into ``video``): its history rows, its solver
    steps' coefficients, the start of its summary row and the coupling time it began at."""
    obs, info = env.reset(seed=seed, options=options)
    if hasattr(controller, "reset"):
        controller.reset()
    rows: list[dict[str, Any]] = []
    coefficients: list[tuple[int, float, float, float]] = []
    t = t0 = float(info.get("time", 0.0))
    total, step = 0.0, 0
    with _recording(env, video) as recording:
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
            rows.append(row)
            for time_, cd, cl in np.asarray(info.get("coefficients", np.zeros((0, 3)))):
                coefficients.append((episode, float(time_), float(cd), float(cl)))
            if recording is not None:
                recording.add(env.render())
            if terminated or truncated:
                break
    summary = {"episode": episode, "steps": step, "return": total, "end_time": t}
    return rows, coefficients, summary, t0


def _recording(env: gym.Env, path: Path | None) -> Any:
    """The episode's video at ``path`` (a context), its first frame (the state after
    reset) added; a context of ``None`` without ``path``."""
    if path is None:
        return contextlib.nullcontext()
    fps = float(env.metadata.get("render_fps") or 4)
    recording = VideoFile(path, fps)
    try:
        recording.add(env.render())
    except BaseException:
        recording.__exit__(None, None, None)
        raise
    return recording


def _metric_names(rows: list[dict[str, Any]]) -> list[str]:
    """The metrics an episode's rows record, in their order."""
    return list(
        dict.fromkeys(
            name
            for r in rows
            for name in r
            if name not in _NOT_METRICS and not name.startswith("action_")
        )
    )


def _write_rollout(
    out: Path,
    history_rows: list[dict[str, Any]],
    coefficient_rows: list[tuple[int, float, float, float]],
    summaries: list[dict[str, Any]],
    columns: list[str],
) -> dict[str, Any]:
    """``history.csv``, ``coefficients.csv`` (only ``columns`` of the coefficients; none
    without any: an earlier run's file is removed, so that plot reads no stale one) and
    ``summary.json``; the summary."""
    _write_csv(out / "history.csv", history_rows)
    _write_coefficients(out / "coefficients.csv", coefficient_rows, columns)
    summary = {
        "episodes": summaries,
        "mean_return": float(np.mean([s["return"] for s in summaries])),
        "over_episodes": over_episodes(summaries),
    }
    (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    return summary


#: the columns of ``info["coefficients"]`` rows after their time, in order
COEFFICIENTS = ("Cd", "Cl")


def coefficient_columns(metrics: list[str]) -> list[str]:
    """The force coefficients an env reports among its ``info["metrics"]`` names: the
    columns of its ``coefficients.csv`` (none for an env without force coefficients)."""
    return [name for name in COEFFICIENTS if name in metrics]


def _write_coefficients(
    path: Path, rows: list[tuple[int, float, float, float]], columns: list[str]
) -> None:
    """``episode, time`` and ``columns`` of every solver step's row; no file (and none
    left from an earlier run) when ``columns`` is empty."""
    if not columns:
        path.unlink(missing_ok=True)
        return
    keep = [2 + COEFFICIENTS.index(name) for name in columns]
    with path.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["episode", "time", *columns])
        writer.writerows([(row[0], row[1], *(row[k] for k in keep)) for row in rows])


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
    coefficients: list[tuple[int, float, float, float]],
    t0: float,
    floor: Reference,
    rows: list[dict[str, Any]] | None = None,
) -> dict[str, float]:
    """The settled mean of the reference's metric (from ``t0 + settle_time`` on) and the
    fractions of the floor that the whole episode's and the settled mean reach.

    A cylinder's ``Cd``/``Cl`` is read over every solver step (``coefficients``:
    ``series_settled_mean_Cd``); any other metric, or one without coefficients, from the
    episode's per-action ``rows`` (``settled_mean_<metric>``). None when neither has it."""
    metric = floor.metric
    if metric in ("Cd", "Cl") and coefficients:
        _, time, cd, cl = np.asarray(coefficients, dtype=float).T
        values, key = (cd if metric == "Cd" else cl), f"series_settled_mean_{metric}"
    else:
        pairs = [(r["time"], r[metric]) for r in rows or () if r.get(metric) is not None]
        if not pairs:
            return {}
        time, values = np.asarray(pairs, dtype=float).T
        key = f"settled_mean_{metric}"
    out = {"floor_fraction": floor.fraction(float(values.mean()))}
    settled = values[time >= t0 + floor.settle_time - 1e-9]
    if settled.size:
        out[key] = float(settled.mean())
        out["settled_floor_fraction"] = floor.fraction(float(settled.mean()))
    return out


def over_episodes(episodes: list[dict[str, Any]]) -> dict[str, dict[str, float | int]]:
    """Mean, standard deviation (``ddof=0``) and count over episodes of each scalar."""
    keys = [
        k
        for k in episodes[0]
        if k not in ("episode", "steps", "end_time", "start", "start_label", "video")
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


def _policy(args: argparse.Namespace, env: LabEnv) -> Policy:
    """The policy to evaluate (``--policy``/``--model``, default ``runs/<env>/train``)."""
    spec = getattr(args, "policy", None)
    try:
        policy = resolve_policy(
            spec if spec is not None else default_out(env, "train"),
            env,
            which=getattr(args, "model", "kept"),
        )
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


#: What the one-line report shows of an env with force coefficients (the cylinders): (summary
#: key, label, % change against a baseline?), their drag and lift over every solver step.
#: No % for the return or the lift: both are about zero uncontrolled (the reward offset is
#: the uncontrolled drag), so a relative change of them says nothing.
_SERIES_REPORTED = (
    ("return", "return", False),
    ("series_mean_Cd", "mean Cd", True),
    ("series_mean_abs_Cl", "mean |Cl|", True),
)


def _reported(stats: dict[str, Any], env_info: LabEnv) -> list[tuple[str, str, bool]]:
    """What the one-line report shows: the cylinders' force coefficients over every solver
    step where recorded, else the episode means of the env's own metrics (its card's
    objective, with its % change against a baseline, then its ``metrics``); then the
    fractions of its reference (a drag floor) where it declares one."""
    if "series_mean_Cd" in stats:
        shown = list(_SERIES_REPORTED)
    else:
        shown = [("return", "return", False)]
        objective = env_info.objective
        for name in env_info.episode_metrics:
            shown.append((f"mean_{name}", f"mean {name}", name == objective))
    if env_info.reference is not None:
        shown.append(("floor_fraction", f"fraction of the {env_info.reference.label}", False))
        shown.append(("settled_floor_fraction", "settled", False))
    return shown


def _report(command: str, summary: dict[str, Any], out: Path, env_info: LabEnv) -> str:
    """One line: mean ± std over the episodes of the return and the env's metrics (the
    cylinders: Cd and |Cl|), with the % change against a baseline where it means something."""
    stats = summary["over_episodes"]
    source = "series" if "series_mean_Cd" in stats else "actions"
    parts = []
    for key, label, relative in _reported(stats, env_info):
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


class _Unusable(Exception):
    """What the user typed cannot run: one line, exit status 2, nothing left running."""


def rollout_command(command: str, args: argparse.Namespace) -> int:
    """``gymprecice evaluate`` / ``baseline`` / ``open-loop`` / ``feedback``."""
    try:
        return _rollout_command(command, args)
    except _Unusable as exc:
        print(f"gymprecice {command}: {exc}", file=sys.stderr)
        return 2


def _rollout_command(command: str, args: argparse.Namespace) -> int:
    try:
        env_info = find_lab_env(args.env)
    except LabEnvError as exc:
        raise _Unusable(str(exc)) from None
    out = (args.out or default_out(env_info, command)).resolve()
    kwargs = build_env_kwargs(args, env_info, out)
    if command == "baseline":  # where the action cannot say "uncontrolled", a kwarg does
        kwargs = {**dict(env_info.baseline_kwargs), **kwargs}
    baseline = _read_baseline(args.baseline) if getattr(args, "baseline", None) else None
    video = _video(args, env_info, out)
    if video is not None:
        kwargs["render_mode"] = "rgb_array"
    policy = _policy(args, env_info) if command == "evaluate" else None
    applied = _policy_kwargs(policy, env_info, args) if policy is not None else {}
    kwargs.update(applied)
    # what was typed is checked before the machine: a bad --law is the user's to fix anywhere
    own_law = _own_law(args, env_info) if command == "feedback" else None
    if not args.double:
        status = require_solvers(env_info, command, verbose=args.require_solvers, kwargs=kwargs)
        if status:
            return status
    # the robustness wrappers' noise is seeded by each episode's reset seed
    try:
        robustness = wrap_spec(getattr(args, "wrap", []))
    except WrapError as exc:
        raise _Unusable(str(exc)) from None
    # The policy acts in [-1, 1] (training rescales); the fixed controllers act in the
    # env's own units, so that "zero" means jets closed.
    env = make_env_checked(
        env_info.name,
        env_info.env_id,
        0,
        kwargs,
        rescale=command == "evaluate",
        robustness=robustness,
    )
    try:
        episodes, starts = _episodes(command, args, env, env_info)
        settings: dict[str, Any] = {
            "robustness": robustness,
            "env_id": env_info.env_id,
            "env_kwargs": kwargs,
            "episodes": episodes,
            "held_out_starts": list(starts) if starts is not None else None,
            "double": args.double,
            "video": str(video) if video is not None else None,
        }
        controller, described = _controller(
            command, args, env, env_info, (policy, applied) if policy else None, own_law
        )
        settings.update(described)
        case_dir = getattr(getattr(env.unwrapped, "config", None), "case_dir", None)
        seeds = {"seed": args.seed, "episode_seeds": [args.seed + i for i in range(episodes)]}
        write_manifest(out, command=command, case_dir=case_dir, seeds=seeds, settings=settings)
        summary = rollout(
            env,
            controller,
            out,
            episodes=episodes,
            seed=args.seed,
            every_start=starts is not None,
            reference=env_info.reference,
            video=video,
        )
        if baseline is not None:
            summary["baseline"] = str(args.baseline.resolve())
            summary["change_percent"] = change_against(summary, baseline)
            (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    finally:
        env.close()
    manifest = {"case_dir": case_dir, "seeds": seeds, "settings": settings}
    solvers = read_manifest(out)["solvers"]  # as found before the rollout
    write_manifest(out, command=command, solvers=solvers, extra={"result": summary}, **manifest)
    print(_report(command, summary, out, env_info))
    return 0


def _video(args: argparse.Namespace, env_info: LabEnv, out: Path) -> Path | None:
    """``--video``'s file (None without it), refused before any solver starts: a format
    that cannot be written here, an env that cannot render."""
    video = getattr(args, "video", None)
    if video is None:
        return None
    try:
        path = check_video_path(video or out / DEFAULT_NAME).resolve()
        check_renders(env_info.env_id)
    except VideoError as exc:
        raise _Unusable(str(exc)) from None
    return path


def _policy_kwargs(policy: Policy, env_info: LabEnv, args: argparse.Namespace) -> dict[str, Any]:
    """The env keyword arguments the policy needs: it acts in [-1, 1], so the env must
    have the action bound it was trained with (each change said in one line)."""
    try:
        applied, lines = policy_env_kwargs(policy, env_info, args.env_kwargs or {})
    except PolicyError as exc:
        raise _Unusable(str(exc)) from None
    for line in lines:
        print(f"gymprecice evaluate: {line}")
    return applied


def _own_law(
    args: argparse.Namespace, env_info: LabEnv
) -> tuple[FeedbackLaw, dict[str, float]] | None:
    """``feedback``'s law: the env's own at ``--law`` (:func:`law_point`), else None for a
    signal fed back, refused where the env names no signal and ``--signal`` none."""
    try:
        own_law = law_point(env_info, getattr(args, "law", None))
    except ValueError as exc:
        raise _Unusable(str(exc)) from None
    if own_law is None and not (args.signal or env_info.feedback_signal):
        raise _Unusable(
            f"{env_info.name} has no default signal; pass --signal "
            "NAME (one of the metrics its steps report in info['metrics']), or declare the "
            "lab card field 'feedback_signal' or 'feedback_law' (card=EnvCard(...) in "
            "register(), docs: Lab reference)"
        )
    return own_law


def _episodes(
    command: str, args: argparse.Namespace, env: gym.Env, env_info: LabEnv
) -> tuple[int, tuple[Any, ...] | None]:
    """How many episodes to run and, with ``--all-starts``, the starts they run from
    (None without it: each episode's start is drawn by its seed)."""
    if not getattr(args, "all_starts", False):
        return args.episodes, None
    try:
        starts = tuple(evaluation_starts(env, args.seed))
        held_out = held_out_starts(env)
    except StartsError as exc:
        raise _Unusable(str(exc)) from None
    if not held_out:
        print(
            f"gymprecice {command}: {env_info.name} has no held-out starts; its starts "
            f"are {starts[0]} to {starts[-1]} (lab card field "
            "'held_out_starts' and the env's held_out_starts property declare others)"
        )
    return len(starts), starts


def _controller(
    command: str,
    args: argparse.Namespace,
    env: gym.Env,
    env_info: LabEnv,
    policy: tuple[Policy, dict[str, Any]] | None,
    own_law: tuple[FeedbackLaw, dict[str, float]] | None,
) -> tuple[Controller, dict[str, Any]]:
    """The command's controller on ``env`` and what the manifest records of it
    (``policy``: evaluate's, with the env keyword arguments applied for it)."""
    if command == "evaluate":
        assert policy is not None
        return _policy_controller(*policy, args, env, env_info)
    if command == "baseline":
        return zero_controller(env.action_space), {}
    if command == "feedback" and own_law is not None:
        law, point = own_law
        try:
            return law.build(env.action_space, point), {"law": env_info.feedback_law, **point}
        except ValueError as exc:
            raise _Unusable(str(exc)) from None
    if command == "feedback":
        signal = str(args.signal or env_info.feedback_signal)
        try:
            feedback = FeedbackController(
                env.action_space, signal, args.gain, args.delay, args.centre
            )
        except (TypeError, ValueError) as exc:
            raise _Unusable(str(exc)) from None
        return feedback, feedback.settings()
    frequency = args.frequency or env_info.open_loop_frequency or default_frequency(env)
    controller = sine_controller(env.action_space, args.amplitude, frequency, args.phase)
    return controller, {"amplitude": args.amplitude, "frequency": frequency, "phase": args.phase}


def _policy_controller(
    policy: Policy,
    applied: dict[str, Any],
    args: argparse.Namespace,
    env: gym.Env,
    env_info: LabEnv,
) -> tuple[Controller, dict[str, Any]]:
    """The trained policy as a controller (its mean action unless ``--stochastic``), its
    observations normalised as in training; refused if it does not fit ``env``."""
    model_path = policy.model
    model = load_model(model_path)
    try:
        check_policy_env(policy, model, env, env_info.name, applied)
    except PolicyError as exc:
        raise _Unusable(str(exc)) from None
    normalizer = load_normalizer(model_path)
    deterministic = not args.stochastic

    def controller(obs: Any, t: float) -> Any:
        if normalizer is not None:
            obs = normalizer.normalize_obs(obs)
        action, _ = model.predict(obs, deterministic=deterministic)
        return action

    return controller, {
        "model": str(model_path.resolve()),
        "policy": policy.describe(),
        "model_sha256": file_sha256(model_path),
        "normalization": str(vecnormalize_path(model_path)) if normalizer else None,
        "deterministic": deterministic,
    }
