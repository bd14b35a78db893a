"""How long a training run had trained at a given moment, summed over its segments.

A run preempted and resumed is several processes, one *segment* each in its manifest
(:mod:`gymprecice_lab.training.segments`). The hours between a stop and its resume are
nobody's training, so "saved 54 min after the command" would be wrong for a model saved
in a resumed segment: what a reader wants is the wall-clock the run spent training up to
that save. Each segment counts from its typed command to its end:

* ``finished_at``, written when the segment ends;
* for a manifest written before that was recorded, the segment's learning ``seconds``
  (a lower bound: its set-up is left out);
* for a segment killed before it wrote either (SIGKILL), up to the next segment's start
  (an upper bound: the gap before the resume counts).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

__all__ = ["total_training_seconds", "training_seconds"]


def _timed(segments: Sequence[Mapping[str, Any]]) -> list[Mapping[str, Any]]:
    """The segments that record their start, in the order they ran."""
    return sorted(
        (s for s in segments if s.get("started_at") is not None),
        key=lambda s: float(s["started_at"]),
    )


def _duration(segment: Mapping[str, Any], next_start: float | None) -> float | None:
    start = float(segment["started_at"])
    if segment.get("finished_at") is not None:
        return float(segment["finished_at"]) - start
    seconds = (segment.get("result") or {}).get("seconds")
    if seconds is not None:
        return float(seconds)
    return None if next_start is None else next_start - start


def training_seconds(segments: Sequence[Mapping[str, Any]], at: float) -> float | None:
    """Seconds of training up to epoch ``at``: every segment begun before ``at`` whole,
    the one running at ``at`` up to it. ``None`` when the segments record no start."""
    timed = _timed(segments)
    if not timed:
        return None
    total = 0.0
    for i, segment in enumerate(timed):
        start = float(segment["started_at"])
        next_start = float(timed[i + 1]["started_at"]) if i + 1 < len(timed) else None
        if next_start is None or at < next_start:
            return total + max(0.0, at - start)
        total += max(0.0, _duration(segment, next_start) or 0.0)
    return total


def total_training_seconds(
    segments: Sequence[Mapping[str, Any]], last_end: float | None = None
) -> float | None:
    """The whole run's training time: every segment's, the gaps left out. ``None`` when
    a segment's end is unknown (the last one still running, or killed without a record).
    ``last_end`` (epoch seconds; the manifest's last write) ends a finished last segment
    recorded before ``finished_at`` was, where its learning seconds would leave out its
    set-up."""
    timed = _timed(segments)
    if not timed:
        return None
    total = 0.0
    for i, segment in enumerate(timed):
        next_start = float(timed[i + 1]["started_at"]) if i + 1 < len(timed) else None
        duration = _duration(segment, next_start)
        if duration is None:
            return None
        finished = segment.get("result") is not None and segment.get("finished_at") is None
        if next_start is None and last_end is not None and finished:
            duration = max(duration, last_end - float(segment["started_at"]))
        total += max(0.0, duration)
    return total
