"""The rollout loop: whole episodes of one env under a fixed controller, recorded.

Each episode runs from reset to its end (terminated or truncated); its actions, metrics
and solver steps' coefficients go to the files of :mod:`gymprecice_lab.rollouts.records`,
its frames to a video where asked (:mod:`gymprecice_lab.rollouts.video`). With
``every_start`` episode k runs the env's held-out start k (:mod:`gymprecice_lab.common.starts`),
or with ``starts="validation"`` its validation start k: the starts that choose a trained
model, where a baseline is tuned without seeing the held-out ones.
"""

from __future__ import annotations

import contextlib
import math
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from gymprecice.plugin.card import Reference
from gymprecice_lab.common.starts import (
    held_out_starts,
    seed_start_label,
    start_options,
    validation_options,
    validation_starts,
)
from gymprecice_lab.rollouts.controllers import Controller
from gymprecice_lab.rollouts.records import (
    coefficient_columns,
    floor_metrics,
    metric_names,
    nanmean,
    series_means,
    write_rollout,
)
from gymprecice_lab.rollouts.video import VideoFile, episode_video_path

__all__ = ["STARTS", "rollout"]

#: which starts ``every_start`` runs: the held-out ones (the test), or the validation ones
STARTS = ("held-out", "validation")


def rollout(
    env: gym.Env,
    controller: Controller,
    out: Path,
    *,
    episodes: int = 1,
    seed: int = 0,
    every_start: bool = False,
    starts: str = "held-out",
    reference: Reference | None = None,
    video: Path | None = None,
) -> dict[str, Any]:
    """Run ``episodes`` whole episodes and write history, coefficients and summary.

    ``every_start``: episode k runs the env's held-out start k (mod their number), the
    same for every controller and seed (an env without held-out starts: its seed
    ``seed + k``, the start labelled so); otherwise the held-out split draws each
    episode's start from its seed (``seed + k``). ``starts="validation"`` (with
    ``every_start``): episode k runs the env's validation start k instead
    (:func:`~gymprecice_lab.common.starts.validation_starts`, mod their number), never a
    held-out one. ``reference`` (the card's, a drag
    floor): each episode's summary also gives its settled mean of the reference's metric
    and the fractions of the floor it reaches. ``video``: each episode's frames (the env
    renders) go to :func:`~gymprecice_lab.rollouts.video.episode_video_path`.
    """
    if starts not in STARTS:
        raise ValueError(f"starts is one of {', '.join(STARTS)}, got {starts!r}")
    out.mkdir(parents=True, exist_ok=True)
    history_rows: list[dict[str, Any]] = []
    coefficient_rows: list[tuple[int, float, float, float]] = []
    summaries = []
    validation = every_start and starts == "validation"
    labels: tuple[str, ...] = ()
    if every_start:
        labels = validation_starts(env) if validation else held_out_starts(env)
    seeded = every_start and not labels  # starts are seeds
    for episode in range(episodes):
        episode_seed = seed + episode
        if validation:
            start_seed, options = validation_options(env, episode)
            episode_seed = episode_seed if start_seed is None else start_seed
        else:
            options = start_options(episode, len(labels))
        path = episode_video_path(video, episode, episodes) if video is not None else None
        rows, coefficients, summary_row, t0 = _episode(
            env, controller, episode, episode_seed, options, path
        )
        if labels:
            summary_row["start"] = episode % len(labels)
            summary_row["start_label"] = labels[episode % len(labels)]
        elif seeded:
            summary_row["start"] = episode
            summary_row["start_label"] = seed_start_label(seed + episode)
        if path is not None:
            summary_row["video"] = str(path)
        summary_row.update(
            {
                f"mean_{name}": nanmean([r.get(name, math.nan) for r in rows])
                for name in metric_names(rows)
            }
        )
        summary_row.update(series_means([c[2:] for c in coefficients]))
        if reference is not None:
            summary_row.update(floor_metrics(coefficients, t0, reference, rows))
        history_rows += rows
        coefficient_rows += coefficients
        summaries.append(summary_row)
    columns = coefficient_columns(metric_names(history_rows))
    return write_rollout(out, history_rows, coefficient_rows, summaries, columns)


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
