"""Interval estimates of a controller's score over training seeds and held-out starts.

Following Agarwal et al. (2021, "Deep RL at the edge of the statistical precipice"), a
benchmark reports for each controller the **mean**, the **median** and the
**interquartile mean** (IQM: the mean of the middle 50 % of all seed x start scores,
robust to one lucky or unlucky seed, and less coarse than the median), each with a **95 % stratified-bootstrap confidence interval**: the training seeds
are resampled with replacement *within each held-out start* (the strata), the statistic
is recomputed on the pooled resample, and the interval is the 2.5 and 97.5 percentiles
of those statistics (the percentile method, as in the ``rliable`` library).

The resampling is :func:`scipy.stats.bootstrap` with one sample per start and
``paired=False``: SciPy then resamples each sample on its own, which is exactly the
stratified bootstrap. ``rliable`` itself is not used: its import fails with the ``arch``
and ``pandas`` releases that pip resolves next to NumPy 2 (``arch`` 7.2 against
``pandas`` 3), and SciPy is all it would add here.

A controller run once (a deterministic baseline: one "seed") has no spread to resample;
its interval is the point itself and ``runs`` says so.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

__all__ = ["Estimate", "estimate", "iqm"]

CONFIDENCE = 0.95


def iqm(values: np.ndarray, axis: int = -1) -> np.ndarray:
    """The interquartile mean: the mean of the middle 50 % (25 % trimmed from each end)."""
    from scipy.stats import trim_mean

    return trim_mean(values, 0.25, axis=axis)


def _mean(values: np.ndarray, axis: int = -1) -> np.ndarray:
    return np.mean(values, axis=axis)


def _median(values: np.ndarray, axis: int = -1) -> np.ndarray:
    return np.median(values, axis=axis)


STATISTICS = {"mean": _mean, "median": _median, "iqm": iqm}


@dataclass(frozen=True)
class Estimate:
    """A statistic over all seed x start scores with its 95 % interval."""

    statistic: str
    value: float
    low: float
    high: float
    runs: int
    starts: int

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def estimate(scores: np.ndarray, statistic: str, *, reps: int = 2000, seed: int = 0) -> Estimate:
    """``statistic`` ("mean", "median" or "iqm") of ``scores`` (runs x starts) with its
    interval."""
    scores = np.asarray(scores, dtype=float)
    if scores.ndim != 2 or not scores.size:
        raise ValueError(
            f"scores must be a non-empty runs x starts array, got shape {scores.shape}"
        )
    if not np.all(np.isfinite(scores)):
        raise ValueError("scores hold NaN or infinity: a run or an evaluation is incomplete")
    func = STATISTICS[statistic]
    runs, starts = scores.shape
    value = float(func(scores.reshape(-1)))
    if runs < 2:
        return Estimate(statistic, value, value, value, runs, starts)
    from scipy.stats import bootstrap

    def pooled(*strata: np.ndarray, axis: int = -1) -> np.ndarray:
        return func(np.concatenate(strata, axis=axis), axis=axis)

    result = bootstrap(
        tuple(scores[:, j] for j in range(starts)),
        pooled,
        n_resamples=reps,
        confidence_level=CONFIDENCE,
        method="percentile",
        paired=False,
        vectorized=True,
        rng=np.random.default_rng(seed),
    )
    low, high = result.confidence_interval
    return Estimate(statistic, value, float(low), float(high), runs, starts)
