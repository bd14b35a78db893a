"""Progress lines while the first reset runs the OpenFOAM pre-run.

On real solvers the first reset of an OpenFOAM env develops the flow before any action (the
jet cylinder: about ten minutes on two cores), inside the env's worker process, whose log is
a file. Without this the terminal would stay silent for those minutes; with it, ``train``
prints the pre-run's simulated time every ``every`` seconds until the pre-run ends.
"""

from __future__ import annotations

import re
import threading
from collections.abc import Callable
from pathlib import Path

#: OpenFOAM prints ``Time = 1.234`` at the start of every time step.
_TIME = re.compile(rb"^Time = ([0-9.eE+-]+)\s*$", re.M)
_TAIL_BYTES = 64 * 1024


def last_time(log: Path) -> float | None:
    """The last ``Time = ...`` of an OpenFOAM log, reading only its tail."""
    try:
        with log.open("rb") as f:
            size = f.seek(0, 2)
            f.seek(max(0, size - _TAIL_BYTES))
            found = _TIME.findall(f.read())
    except OSError:
        return None
    return float(found[-1]) if found else None


class PrerunProgress:
    """A daemon thread that reports ``<envs_dir>/env_*/*/log.prerun.*`` as they grow."""

    def __init__(
        self,
        envs_dir: Path,
        end_time: float | None = None,
        every: float = 30.0,
        say: Callable[[str], None] = lambda line: print(line, flush=True),
    ) -> None:
        self.envs_dir = Path(envs_dir)
        self.end_time = end_time
        self.every = every
        self.say = say
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="prerun-progress", daemon=True)
        self._reported: dict[Path, float] = {}

    def __enter__(self) -> PrerunProgress:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join(timeout=5)

    def poll(self) -> list[str]:
        """One round: a line per pre-run log whose simulated time moved since the last."""
        lines = []
        for log in sorted(self.envs_dir.glob("env_*/*/log.prerun.*")):
            time = last_time(log)
            if time is None or self._reported.get(log) == time:
                continue
            self._reported[log] = time
            total = f" of {self.end_time:g} s" if self.end_time else ""
            env = log.relative_to(self.envs_dir).parts[0]
            lines.append(f"gymprecice train: {env} pre-run at t = {time:g} s{total} ({log})")
        return lines

    def _run(self) -> None:
        while not self._stop.wait(self.every):
            for line in self.poll():
                self.say(line)
