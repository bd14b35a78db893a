"""Which rows of a solver output belong to the step that just ended.

Solvers run ahead of the controller: by the time an env reads the output of the step that
ended at ``t``, the solver may already have written rows of the next step. A reader that
handed back every new row would make an observation (the last row) or a reward (the mean
over the step) depend on how far the solver got, so the same seed and actions would give
different episodes. Every reader gymprecice ships (the watch-point reader and the OpenFOAM
plugin's readers) therefore keeps its rows in time order and hands out, from
``wait_until(t)``, only the rows of the step ``(t_prev, t]``; rows past ``t`` stay for the
next read. :func:`rows_through` is that split, for a plugin's own reader to use too (see
:class:`~gymprecice.solver.WaitableOutputReader`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

__all__ = ["rows_through", "time_tolerance"]


def time_tolerance(time: float, relative: float) -> float:
    """The absolute tolerance within which an output's time is ``time``.

    Outputs print times to a few significant digits, so a row of ``t = 0.1`` may read
    0.10000000 while ``Adapter.time`` is 0.1 + 1e-17: ``relative`` of ``|time|``, and of 1
    near zero.
    """
    return relative * max(1.0, abs(time))


def rows_through(
    times: Sequence[float] | np.ndarray,
    time: float,
    relative: float = 1e-9,
    *,
    handed_out: float | None = None,
) -> int:
    """How many of the leading rows belong to the step that ends at ``time``.

    ``times`` are the times of the rows not yet handed out, in the order the solver wrote
    them. The step's rows are the leading run of rows at or before ``time`` (within
    :func:`time_tolerance`): the row at ``time`` itself and every row before it, the
    rows of every coupling iteration included (an implicitly coupled solver writes a
    window's times again on each iteration). When the output has no row at ``time`` (it
    writes every few steps), the first row after ``time`` ends the step instead, so a
    reader that waited for a row at or after ``time`` always hands one out, unless
    ``handed_out`` (the time of the newest row the reader has already handed out, if
    any) shows that the step ended before these rows. Rows after that stay for the next
    step. The answer depends only on the times, never on how far the solver has written,
    which is what makes a step's rows deterministic.
    """
    tolerance = time_tolerance(time, relative)
    count = 0
    for value in times:
        if value > time + tolerance:
            break
        count += 1
    reached = count > 0 and times[count - 1] >= time - tolerance
    if handed_out is not None and count == 0 and handed_out >= time - tolerance:
        reached = True  # the step's last row went out before (through read_new)
    if count < len(times) and not reached:
        count += 1  # no row at `time`: the first row after it closes the step
    return count
