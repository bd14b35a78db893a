"""A wall-clock duration as every lab command prints it: ``45 s``, ``9 min 05 s``,
``1 h 02 min 05 s``; or to the minute (``17 min``, ``1 h 02 min``) under a table, where
seconds would be noise.

One function, so that ``train``, ``time-to-floor`` and ``benchmark`` write the same
duration the same way (a reader compares their lines side by side).
"""

from __future__ import annotations

import math

__all__ = ["duration_text"]


def duration_text(seconds: float | None, *, to_the_minute: bool = False) -> str:
    """``seconds`` as text; ``None`` is ``an unknown time`` and an infinite duration (a
    level never reached) ``not reached``."""
    if seconds is None:
        return "an unknown time"
    if not math.isfinite(seconds):
        return "not reached"
    if to_the_minute:
        hours, minutes = divmod(round(seconds / 60), 60)
        return f"{hours} h {minutes:02d} min" if hours else f"{minutes} min"
    hours, rest = divmod(round(seconds), 3600)
    minutes, rest = divmod(rest, 60)
    if hours:
        return f"{hours} h {minutes:02d} min {rest:02d} s"
    return f"{minutes} min {rest:02d} s" if minutes else f"{rest} s"
