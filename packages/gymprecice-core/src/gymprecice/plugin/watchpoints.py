"""Read preCICE watch-point logs while the solver is still writing them.

A ``<watch-point name="Flap-Tip" mesh="Solid-Mesh" coordinate="0.0;1"/>`` of participant
``Solid`` makes preCICE write ``precice-Solid-watchpoint-Flap-Tip.log`` in the participant's
working directory: the cheapest way to observe a solver, whatever the solver is. Layout
(preCICE v3, ``WatchPoint`` with ``io::TXTTableWriter``)::

      Time  Coordinate0  Coordinate1  Displacement0  Displacement1  Force0  Force1
     0.00000000e+00   0.00000000e+00   1.00000000e+00   0.00000000e+00  ...
     1.00000000e-02   ...

* one header line of whitespace-separated column names: ``Time``, then the interpolated
  ``Coordinate`` of the watched point, then every data the watched mesh uses, in the order
  of its ``<use-data>`` tags; a vector of a ``d``-dimensional mesh has ``d`` columns named
  ``<name>0`` .. ``<name>{d-1}``, a scalar one column named ``<name>``;
* one row per completed time window (plus one at initialisation, time 0), every value in
  C++ ``std::scientific`` with 8 digits, right-aligned in 15 characters, two spaces apart;
* the writer puts the newline *before* each row, not after it, and flushes at the end of
  each row, so the file never ends with a newline and the last row is complete although
  unterminated. Only the last (unterminated) row can ever be half written.

So this reader accepts a newline-terminated row as complete, and the unterminated last row
only when it has every column and its last value is a whole scientific number (mantissa,
``e``, sign and at least two exponent digits, or ``nan``/``inf``); anything else waits for
more bytes. A file that does not exist yet reads as empty: preCICE creates it only when the
participant configures itself. :meth:`WatchPointLog.wait_until` blocks until the row of a
given time is in, because the solver writes its row a moment after the coupling partner's
``advance`` has returned, and hands out only the rows up to that time: a solver that runs
ahead of the controller may already have written the next step's rows, and those stay for
the next read (:mod:`gymprecice.readers`).

preCICE writes a watch point for any participant whatever its solver, so core opens one
for any solver: ``self.open_output("solid", "watchpoint", point="Flap-Tip")`` in an env
(:func:`open_watch_point`, core's answer to ``gymprecice_open_output``).
"""

from __future__ import annotations

import os
import re
import time as _time
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from gymprecice.plugin.errors import ConfigError, GymPreciceError
from gymprecice.plugin.readers import rows_through, time_tolerance

if TYPE_CHECKING:
    from gymprecice.plugin.solver import SolverContext

__all__ = [
    "OUTPUT",
    "WatchPointError",
    "WatchPointLog",
    "WatchPointTimeoutError",
    "open_watch_point",
    "parse_header",
    "watch_point_file_name",
]

#: the output name of a watch point: ``open_output(solver, "watchpoint", point=...)``
OUTPUT = "watchpoint"
#: times in the log have 9 significant digits (``std::scientific``, 8 decimals)
_RELATIVE_TIME_TOLERANCE = 1e-8

#: one complete value as C++ streams write doubles in scientific notation
_COMPLETE_VALUE = re.compile(r"[-+]?(?:\d+\.?\d*[eE][-+]\d{2,}|nan|inf)", re.IGNORECASE)


class WatchPointError(GymPreciceError, ValueError):
    """A watch-point log does not have the layout preCICE writes."""


class WatchPointTimeoutError(GymPreciceError, TimeoutError):
    """The row of the requested time did not appear in the log within the timeout."""


def watch_point_file_name(participant: str, name: str) -> str:
    """File name preCICE v3 gives a watch point: ``precice-<participant>-watchpoint-<name>.log``."""
    return f"precice-{participant}-watchpoint-{name}.log"


@dataclass(frozen=True)
class Field:
    """One named quantity of the log and the columns it occupies (``stop`` excluded)."""

    name: str
    start: int
    stop: int

    @property
    def width(self) -> int:
        return self.stop - self.start


def parse_header(columns: list[str]) -> dict[str, Field]:
    """Group header columns into fields: ``Coordinate0 Coordinate1`` -> ``Coordinate``.

    The mesh dimension is the number of ``Coordinate<i>`` columns; a vector field has
    exactly that many consecutive ``<name>0 .. <name>{d-1}`` columns. Grouping by the
    dimension keeps a scalar that merely ends in a digit (``Pressure2``) a scalar.
    """
    if not columns or columns[0] != "Time":
        raise ValueError(f"the first column must be 'Time', got {columns[:1]}")
    dim = 0
    while f"Coordinate{dim}" in columns[1 + dim : 2 + dim]:
        dim += 1
    fields: dict[str, Field] = {}
    i = 0
    while i < len(columns):
        name = columns[i]
        base = name[:-1]
        group = [f"{base}{k}" for k in range(dim)]
        if dim > 1 and name.endswith("0") and columns[i : i + dim] == group:
            fields[base] = Field(base, i, i + dim)
            i += dim
        else:
            fields[name] = Field(name, i, i + 1)
            i += 1
    return fields


class WatchPointLog:
    """Incremental reader of one watch-point log (a ``WaitableOutputReader``).

    Rows come back as a float array of shape ``(k, n_columns)`` (``(0, n_columns)`` when
    there are none, ``(0, 0)`` while the header is unknown), column 0 the time:

    * :meth:`wait_until` ``(t, timeout)``: the rows of the step that ended at ``t``, those
      after the previous ``wait_until`` up to the row of ``t``; rows the solver wrote past
      ``t`` stay for the next read. Asked again for the same ``t``, it returns the same
      rows, so an env's observation and reward can both ask for them.
    * :meth:`read_new`: every row not handed out yet, whatever its time.

    Every row handed out stays in :attr:`data`, and :meth:`field` slices one quantity out
    of rows (``field("Displacement", rows)``). A file that is replaced or truncated (a new
    episode in the same directory) is read again from its start. Open one in an env with
    ``self.open_output(solver, "watchpoint", point=name)``; core closes it at every reset.
    """

    #: preCICE's watch-point log counts time from 0 in every run (see
    #: :class:`~gymprecice.solver.WaitableOutputReader`)
    start_time: float | None = 0.0

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.columns: list[str] | None = None
        self.fields: dict[str, Field] = {}
        self._handle = None
        self._inode: tuple[int, int] | None = None
        self._offset = 0
        self._buffer = ""
        self._line = 0  # lines consumed (for error messages)
        self._pending: list[list[float]] = []  # read from the file, not handed out yet
        self._handed: list[list[float]] = []  # handed out by read_new / wait_until
        self._step: tuple[float, np.ndarray] | None = None  # the last wait_until's answer
        self._closed = False

    @classmethod
    def for_watch_point(cls, directory: str | Path, participant: str, name: str) -> WatchPointLog:
        """The log of watch point ``name`` of ``participant`` in ``directory``."""
        return cls(Path(directory) / watch_point_file_name(participant, name))

    # -- OutputReader ----------------------------------------------------------------------
    def read_new(self) -> np.ndarray:
        """Every complete row not handed out yet (see the class docstring for the shape)."""
        self._poll()
        return self._hand_out(len(self._pending))

    def close(self) -> None:
        self._closed = True
        self._close_handle()

    # -- queries ---------------------------------------------------------------------------
    @property
    def data(self) -> np.ndarray:
        """Every row handed out so far (call :meth:`read_new` or :meth:`wait_until` to read on)."""
        return self._as_array(self._handed)

    @property
    def latest_time(self) -> float | None:
        """Time of the newest row handed out so far, ``None`` before the first."""
        return self._handed[-1][0] if self._handed else None

    def field(self, name: str, rows: np.ndarray | None = None) -> np.ndarray:
        """Values of ``name`` (``"Time"``, ``"Coordinate"``, a data name) in ``rows``.

        ``rows`` defaults to :attr:`data`. Scalars come back with shape ``(k,)``, vectors
        with ``(k, dim)``.
        """
        if not self.fields:
            self._poll()
        if name not in self.fields:
            known = sorted(self.fields) or "none yet (the header has not been written)"
            raise KeyError(f"{self.path}: no column {name!r}; the fields are {known}")
        spec = self.fields[name]
        table = self.data if rows is None else np.asarray(rows, dtype=float)
        if spec.width == 1:
            return table[:, spec.start] if table.size else np.zeros(0)
        return table[:, spec.start : spec.stop] if table.size else np.zeros((0, spec.width))

    def wait_until(self, time: float, timeout: float, poll_interval: float = 0.02) -> np.ndarray:
        """Block until the row of ``time`` (or a later one) is in; return the step's rows.

        The step's rows are the rows not handed out yet up to the row of ``time``
        (:func:`~gymprecice.readers.rows_through`); rows of later times stay for the next
        read. A second call for the same ``time`` returns the same rows. Raises
        :class:`WatchPointTimeoutError` after ``timeout`` seconds, saying whether the file
        exists and which time it last showed. ``time`` matches within the 9 significant
        digits the log keeps.
        """
        tolerance = time_tolerance(time, _RELATIVE_TIME_TOLERANCE)
        if self._step is not None and abs(self._step[0] - time) <= tolerance:
            return self._step[1].copy()
        deadline = _time.monotonic() + max(0.0, timeout)
        while True:
            self._poll()
            latest = self._seen_time()
            if latest is not None and latest >= time - tolerance:
                count = rows_through(
                    [row[0] for row in self._pending],
                    time,
                    _RELATIVE_TIME_TOLERANCE,
                    handed_out=self.latest_time,
                )
                rows = self._hand_out(count)
                self._step = (time, rows.copy())
                return rows
            if _time.monotonic() >= deadline:
                if not self.path.exists():
                    state = (
                        "the file does not exist (is the watch point in the participant's "
                        "configuration, and does the solver run in this directory?)"
                    )
                elif latest is None:
                    state = "the file has no complete row yet"
                else:
                    state = f"its last complete row is at time {latest!r}"
                raise WatchPointTimeoutError(
                    f"{self.path}: no row for time {time!r} within {timeout:g} s; {state}"
                )
            _time.sleep(poll_interval)

    # -- internals -------------------------------------------------------------------------
    def _seen_time(self) -> float | None:
        """Time of the newest complete row read from the file, handed out or not."""
        if self._pending:
            return self._pending[-1][0]
        return self.latest_time

    def _hand_out(self, count: int) -> np.ndarray:
        rows, self._pending = self._pending[:count], self._pending[count:]
        self._handed.extend(rows)
        return self._as_array(rows)

    def _as_array(self, rows: list[list[float]]) -> np.ndarray:
        width = len(self.columns) if self.columns else 0
        if not rows:
            return np.zeros((0, width))
        return np.asarray(rows, dtype=float)

    def _close_handle(self) -> None:
        if self._handle is not None:
            self._handle.close()
            self._handle = None

    def _restart(self) -> None:
        """Forget what was read: the file was replaced or truncated."""
        self._close_handle()
        self.columns = None
        self.fields = {}
        self._inode = None
        self._offset = 0
        self._buffer = ""
        self._line = 0
        self._pending = []
        self._handed = []
        self._step = None

    def _poll(self) -> None:
        if self._closed:
            raise ValueError(f"{self.path}: the watch-point reader is closed")
        try:
            stat = os.stat(self.path)
        except FileNotFoundError:
            if self._inode is not None:  # deleted: the next file starts a new log
                self._restart()
            return
        inode = (stat.st_dev, stat.st_ino)
        if self._inode is not None and (inode != self._inode or stat.st_size < self._offset):
            self._restart()
        if self._handle is None:
            self._handle = open(self.path, "rb")  # noqa: SIM115 - kept open across polls
            self._inode = inode
        self._handle.seek(self._offset)
        chunk = self._handle.read()
        if not chunk:
            return
        self._offset += len(chunk)
        self._buffer += chunk.decode("ascii", errors="replace")
        self._consume()

    def _consume(self) -> None:
        """Turn complete lines of the buffer into rows; keep an unfinished tail."""
        if self.columns is None:
            end = self._buffer.find("\n")
            if end < 0:
                return  # the header itself is followed by the first row's newline
            header = self._buffer[:end].split()
            self._buffer = self._buffer[end + 1 :]
            self._line += 1
            try:
                self.fields = parse_header(header)
            except ValueError as exc:
                raise WatchPointError(
                    f"{self.path}:1: not a preCICE watch-point log: {exc}"
                ) from None
            self.columns = header
        *complete, tail = self._buffer.split("\n")
        for line in complete:
            self._line += 1
            self._add(line, self._line, terminated=True)
        if tail.strip() and self._add(tail, self._line + 1, terminated=False):
            tail = ""  # its line is counted when the next row's newline arrives
        self._buffer = tail

    def _add(self, line: str, number: int, *, terminated: bool) -> bool:
        """Parse row ``number``; ``False`` (nothing stored) when an unterminated row is partial."""
        assert self.columns is not None
        parts = line.split()
        if not parts:
            return True
        n = len(self.columns)
        if not terminated and (len(parts) != n or not _COMPLETE_VALUE.fullmatch(parts[-1])):
            return False
        if len(parts) != n:
            raise WatchPointError(
                f"{self.path}:{number}: {len(parts)} values, but the header names {n} "
                f"columns ({' '.join(self.columns)})"
            )
        try:
            row = [float(p) for p in parts]
        except ValueError:
            if not terminated:
                return False
            raise WatchPointError(
                f"{self.path}:{number}: not a row of numbers: {line.strip()!r}"
            ) from None
        self._pending.append(row)
        return True


# -- opening a participant's watch point ---------------------------------------------------


def watch_point_options(
    solver: SolverContext, options: Mapping[str, Any]
) -> tuple[str, str | None]:
    """The watch point and participant that ``open_output(solver, "watchpoint", ...)`` asks for.

    ``point`` (or ``name``) names the ``<watch-point>``; ``participant`` defaults to the
    solver's. ``point`` is the keyword an env passes, because ``Adapter.open_output``
    already takes the output's name as ``name``. Any other key is a :class:`ConfigError`.
    """
    unknown = sorted(set(options) - {"name", "point", "participant"})
    point = options.get("point") or options.get("name")
    if unknown or not point:
        raise ConfigError(
            f"{solver.describe()}: open_output({solver.name!r}, {OUTPUT!r}, point=...) needs "
            f"the watch point's name (and optionally participant=...); got {dict(options)!r}"
        )
    participant = options.get("participant") or solver.participant
    return str(point), (str(participant) if participant else None)


def undeclared_watch_point(solver: SolverContext, participant: str, point: str) -> str | None:
    """Why preCICE writes no log of ``point`` for ``participant``, or ``None`` if it does.

    preCICE writes a watch-point log only for a ``<watch-point>`` of the participant in the
    env's ``precice-config.xml``; the message names the file and the tag to add.
    """
    precice = solver.precice
    if precice is None:
        return None  # nothing to check against
    if participant not in precice.participants:
        return (
            f"{precice.path}: no participant {participant!r} to write watch point {point!r}; "
            f"the participants are {sorted(precice.participants)} (set the solver's "
            "participant in gymprecice-config.json, or pass participant=...)"
        )
    known = [w.name for w in precice.participants[participant].watch_points]
    if point in known:
        return None
    return (
        f"{precice.path}: participant {participant!r} has no <watch-point name={point!r}>; "
        f"its watch points are {known}. Add one inside <participant name={participant!r}>, "
        f'e.g. <watch-point mesh="<a mesh it provides>" name="{point}" coordinate="x;y" />'
    )


def open_watch_point(
    solver: SolverContext, options: Mapping[str, Any], *, participant: str | None = None
) -> WatchPointLog:
    """A reader of the watch point ``options`` name, in the solver's run directory.

    What core answers to ``open_output(solver, "watchpoint", point=...)`` for any solver
    whose participant it knows, whatever the solver's kind: preCICE, not the solver,
    writes the log, ``precice-<participant>-watchpoint-<point>.log`` in the participant's
    working directory. ``participant`` is the fallback when neither ``options`` nor the
    solver's configuration names one (a plugin that reads it from the solver's own files
    passes it). Raises :class:`~gymprecice.errors.ConfigError` naming the fix when the
    participant is unknown or declares no such watch point.
    """
    point, named = watch_point_options(solver, options)
    participant = named or participant
    if participant is None:
        raise ConfigError(
            f"{solver.describe()}: whose watch point {point!r}? Set the solver's "
            f'"participant" in {solver.config_file or "gymprecice-config.json"} or pass '
            f"open_output({solver.name!r}, {OUTPUT!r}, point={point!r}, participant=...)"
        )
    problem = undeclared_watch_point(solver, participant, point)
    if problem:
        raise ConfigError(problem)
    return WatchPointLog(solver.run_dir / watch_point_file_name(participant, point))
