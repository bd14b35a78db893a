"""Where the time of a training run goes: solver, env code, learner, vector env, resets.

A CFD training run is slow, and the first question is always *why*: is the learner
starved by the solvers, are the solvers idle while the learner updates, does the vector
env itself cost anything, are resets the bottleneck? :class:`Telemetry` answers it from
numbers every layer already measures:

* ``solver_wait_s``: time the env waited for the solvers in a step, in preCICE or for
  their output files (the Adapter's ``info["timing"]["wait_s"]``);
* ``env_s``: time in the env's own Python code in a step (``info["timing"]["env_s"]``;
  for envs that report no timing, the whole ``env.step`` as measured by the worker);
* ``env_step_s``: the whole ``env.step`` call as measured in the env's worker process;
* ``vector_overhead_s``: per env and step, the round trip seen by the learner's process
  minus ``env_step_s`` (pickling, pipes, scheduling: the vector env's own cost);
* ``learner_s``: time between one batch step returning and the next one being sent
  (the learner's forward passes, updates, logging);
* ``reset_s``: one env reset (the Adapter's ``info["timing"]["reset_s"]``, or as measured
  by the worker); ``spawn_s``: starting an env worker (construction of the env);
* failures, by env and kind, and divergences (solvers the agent drove past what they
  integrate: episode outcomes, counted apart from failures).

Each series keeps a total (mean over the whole run), a bounded window of recent samples
(percentiles of :meth:`Telemetry.summary`), and the samples since the last
:meth:`Telemetry.drain` (what a logger writes every rollout). Memory stays bounded over
runs of days.
"""

from __future__ import annotations

import math
from collections import Counter, deque
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["SERIES", "SeriesStats", "Telemetry"]

#: The timing series, in the order the summary prints them, with a label each.
SERIES: dict[str, str] = {
    "solver_wait_s": "solver (waiting in preCICE or for output)",
    "env_s": "env code",
    "env_step_s": "env.step (whole, in worker)",
    "vector_overhead_s": "vector env overhead",
    "learner_s": "learner (between steps)",
    "batch_step_s": "batch step (all envs)",
    "reset_s": "reset",
    "spawn_s": "worker start",
}

_PERCENTILES = (50, 90, 99)


@dataclass(frozen=True)
class SeriesStats:
    """Statistics of one timing series (seconds)."""

    count: int
    mean: float
    p50: float
    p90: float
    p99: float
    max: float
    total: float

    def as_dict(self, prefix: str = "") -> dict[str, float]:
        return {
            f"{prefix}mean": self.mean,
            f"{prefix}p50": self.p50,
            f"{prefix}p90": self.p90,
            f"{prefix}p99": self.p99,
            f"{prefix}max": self.max,
            f"{prefix}count": float(self.count),
        }


def _stats(samples: Iterable[float], count: int | None = None, total: float | None = None):
    values = np.fromiter(samples, dtype=float)
    if values.size == 0:
        return None
    p50, p90, p99 = np.percentile(values, _PERCENTILES)
    n = int(values.size) if count is None else count
    tot = float(values.sum()) if total is None else total
    return SeriesStats(
        count=n,
        mean=tot / n if n else math.nan,
        p50=float(p50),
        p90=float(p90),
        p99=float(p99),
        max=float(values.max()),
        total=tot,
    )


class _Series:
    """One timing series. ``add`` only appends (it runs per env step in the learner's
    process); samples are checked and folded into the statistics when they are read."""

    __slots__ = ("count", "peak", "pending", "recent", "total", "window")

    #: fold automatically past this many unread samples (a run nobody reads stays bounded)
    FOLD_AT = 4096

    def __init__(self, window: int) -> None:
        self.window: deque[float] = deque(maxlen=window)
        self.pending: list[Any] = []
        self.recent: list[float] = []
        self.count = 0
        self.total = 0.0
        self.peak = 0.0

    def add(self, value: Any) -> None:
        self.pending.append(value)
        if len(self.pending) >= self.FOLD_AT:
            self.fold()

    def fold(self, recent_limit: int = 100_000) -> None:
        values = []
        for raw in self.pending:
            try:
                value = float(raw)
            except (TypeError, ValueError):
                continue
            if math.isfinite(value) and value >= 0:
                values.append(value)
        self.pending = []
        if not values:
            return
        self.window.extend(values)
        self.count += len(values)
        self.total += math.fsum(values)
        self.peak = max(self.peak, max(values))
        self.recent.extend(values)
        if len(self.recent) > recent_limit:
            del self.recent[: len(self.recent) - recent_limit // 2]


class Telemetry:
    """Timing and failure records of one vector env (see the module docstring).

    ``window`` bounds the samples kept per series for percentiles; ``recent_limit``
    bounds what accumulates between two :meth:`drain` calls (a run that never drains,
    e.g. without the SB3 callback, must not grow without bound).
    """

    def __init__(self, num_envs: int = 0, window: int = 10_000, recent_limit: int = 100_000):
        self.num_envs = num_envs
        self._window = window
        self._recent_limit = recent_limit
        self._series: dict[str, _Series] = {}
        self._wait = self._get("solver_wait_s")
        self._env = self._get("env_s")
        self._env_step = self._get("env_step_s")
        self._overhead = self._get("vector_overhead_s")
        self.steps = 0
        self.episodes = 0
        self.failures: list[Any] = []
        self._recent_failures = 0
        #: steps in which a solver diverged (an episode outcome, not a failure)
        self.divergences = 0
        self._recent_divergences = 0
        self.respawns = 0

    # -- recording -------------------------------------------------------------------------
    def _get(self, name: str) -> _Series:
        series = self._series.get(name)
        if series is None:
            series = self._series[name] = _Series(self._window)
        return series

    def add(self, name: str, value: float | None) -> None:
        """Add one sample (seconds) to series ``name`` (non-finite or negative: ignored)."""
        if value is not None:
            self._get(name).add(value)

    def record_step(
        self, info: Mapping[str, Any] | None, worker_s: float, roundtrip_s: float
    ) -> None:
        """One env step: the env's own timing (if it reports any) and the worker's.

        Called once per env and step in the learner's process, so it only appends.
        """
        self.steps += 1
        if isinstance(info, Mapping) and info.get("diverged"):
            self.divergences += 1
            self._recent_divergences += 1
        # info["timing"] is the Adapter's Timing: a Mapping, not a dict
        timing = info.get("timing") if isinstance(info, Mapping) else None
        if isinstance(timing, Mapping):
            wait = timing.get("wait_s")
            if wait is None:
                wait = timing.get("precice_s")
            if wait is not None:
                self._wait.add(wait)
            self._env.add(timing.get("env_s", worker_s))
        else:
            self._env.add(worker_s)
        self._env_step.add(worker_s)
        self._overhead.add(roundtrip_s - worker_s if roundtrip_s > worker_s else 0.0)

    def record_reset(self, info: Mapping[str, Any] | None, worker_s: float) -> None:
        """One successful env reset (an episode starts)."""
        self.episodes += 1
        timing = info.get("timing") if isinstance(info, Mapping) else None
        reset_s = timing.get("reset_s") if isinstance(timing, Mapping) else None
        self.add("reset_s", worker_s if reset_s is None else reset_s)

    def record_failure(self, failure: Any) -> None:
        """One env failure (an :class:`~gymprecice.vector.EnvFailure`)."""
        self.failures.append(failure)
        if len(self.failures) > self._window:
            del self.failures[: len(self.failures) - self._window]
        self._recent_failures += 1

    # -- reading -----------------------------------------------------------------------------
    def stats(self, name: str) -> SeriesStats | None:
        """Whole-run count/mean/max with percentiles over the recent window."""
        series = self._series.get(name)
        if series is None:
            return None
        series.fold(self._recent_limit)
        if not series.count:
            return None
        stats = _stats(series.window, series.count, series.total)
        if stats is None:
            return None
        return SeriesStats(
            stats.count, stats.mean, stats.p50, stats.p90, stats.p99, series.peak, stats.total
        )

    def drain(self) -> dict[str, float]:
        """Statistics of the samples since the previous drain, flat, for a logger.

        Keys are ``<series>_mean``, ``<series>_p50``, ... plus ``failures`` and
        ``divergences`` (since the last drain), ``failures_total``, ``divergences_total`` and ``solver_fraction``/``learner_fraction`` (of
        the time accounted for in this period).
        """
        out: dict[str, float] = {}
        totals: dict[str, float] = {}
        for name, series in self._series.items():
            series.fold(self._recent_limit)
            stats = _stats(series.recent)
            series.recent = []
            if stats is None:
                continue
            totals[name] = stats.total
            out.update(stats.as_dict(f"{name}_"))
        out["failures"] = float(self._recent_failures)
        out["failures_total"] = float(len(self.failures))
        out["divergences"] = float(self._recent_divergences)
        out["divergences_total"] = float(self.divergences)
        self._recent_failures = self._recent_divergences = 0
        out.update(_fractions(totals, self.num_envs))
        return out

    def failure_counts(self) -> dict[int, Counter[str]]:
        """Per env index: how many failures of each type."""
        counts: dict[int, Counter[str]] = {}
        for failure in self.failures:
            counts.setdefault(failure.env_index, Counter())[_failure_label(failure)] += 1
        return counts

    def summary(self) -> str:
        """A text report of the whole run, meant to be printed at its end."""
        lines = [
            f"gymprecice vector env: {self.num_envs} envs, {self.steps} env steps, "
            f"{self.episodes} episodes started, {len(self.failures)} failures, "
            f"{self.divergences} divergences, "
            f"{self.respawns} worker restarts"
        ]
        width = max(len(label) for label in SERIES.values()) + 2  # labels never push columns
        header = f"  {'[seconds]':<{width}}{'count':>8}" + "".join(
            f"{name:>11}" for name in ("mean", "p50", "p90", "p99", "max")
        )
        rows = []
        totals: dict[str, float] = {}
        for name, label in SERIES.items():
            stats = self.stats(name)
            if stats is None:
                continue
            totals[name] = stats.total
            rows.append(
                f"  {label:<{width}}{stats.count:>8}{stats.mean:>11.4g}{stats.p50:>11.4g}"
                f"{stats.p90:>11.4g}{stats.p99:>11.4g}{stats.max:>11.4g}"
            )
        if rows:
            lines += [header, *rows]
        fractions = _fractions(totals, self.num_envs)
        if fractions:
            lines.append(
                "  share of env-time per step: "
                + ", ".join(
                    f"{key.removesuffix('_fraction')} {100 * value:.1f}%"
                    for key, value in fractions.items()
                )
            )
        counts = self.failure_counts()
        if counts:
            lines.append("  failures by env:")
            for index in sorted(counts):
                kinds = ", ".join(f"{kind} x{n}" for kind, n in counts[index].most_common())
                lines.append(f"    env {index}: {sum(counts[index].values())} ({kinds})")
        return "\n".join(lines)


def _fractions(totals: Mapping[str, float], num_envs: int) -> dict[str, float]:
    """How the env-time of steps splits into solver, env code, overhead and learner.

    Learner time is counted once per batch while the other series are per env, so it is
    weighted by the number of envs (every env idles while the learner works).
    """
    parts = {
        "solver": totals.get("solver_wait_s", 0.0),
        "env": max(0.0, totals.get("env_step_s", 0.0) - totals.get("solver_wait_s", 0.0)),
        "overhead": totals.get("vector_overhead_s", 0.0),
        "learner": totals.get("learner_s", 0.0) * max(1, num_envs),
    }
    whole = sum(parts.values())
    if whole <= 0:
        return {}
    return {f"{key}_fraction": value / whole for key, value in parts.items()}


def _failure_label(failure: Any) -> str:
    kind = getattr(failure, "kind", "error")
    if kind == "error":
        return str(getattr(failure, "type", "error")).rsplit(".", 1)[-1]
    return kind
