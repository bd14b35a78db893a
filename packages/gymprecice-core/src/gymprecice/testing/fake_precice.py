"""A pure-Python stand-in for pyprecice v3 (``import precice``), faithful enough to test against.

Real preCICE is a C++ library that has to be built and installed before pyprecice can be,
so most machines that run gymprecice's tests do not have it. This module speaks the same Python API as the
``pyprecice`` bindings (``Participant`` with the same method names, argument order, return
shapes and dtypes), follows the same call protocol, and fails the same way, so that code
written and tested against it runs unchanged against the real library.

Use it wherever ``import precice`` would go::

    from gymprecice.testing import fake_precice as precice

    participant = precice.Participant("Controller", "precice-config.xml", 0, 1)

or select it for a gymprecice environment with ``"precice": {"library":
"gymprecice.testing.fake_precice"}`` (or ``GYMPRECICE_PRECICE_LIBRARY``). Every participant of
one coupled run must use the double: it only talks to itself (a real preCICE partner is
detected and reported, see below).

How it works
    Each participant is its own process. ``initialize()`` connects to the coupling partners
    named by the ``<m2n:...>`` tags over Unix-domain sockets; the acceptor publishes the
    socket address in ``<exchange-directory>/precice-run/<acceptor>-<connector>/`` (relative
    to the working directory, like preCICE) and the connector waits for it without a timeout,
    like preCICE. Provided meshes are sent to the participants that receive them, then the
    coupling schemes exchange data exactly in the order preCICE's schemes do.

Modelled (as preCICE 3.4 does it)
    * ``serial-explicit``, ``parallel-explicit``, ``serial-implicit``, ``parallel-implicit``
      and ``multi`` schemes, and several schemes per participant (preCICE's compositional
      scheme: any number of explicit ones plus at most one implicit one).
    * ``max-time``, ``max-time-windows``, ``time-window-size``, ``get_max_time_step_size``
      shrinking at the end (truncated last window), subcycling, ``is_time_window_complete``.
    * implicit coupling: ``max-iterations``, ``min-iterations`` and the absolute, relative,
      absolute-or-relative and residual-relative convergence measures (with ``suffices`` and
      ``strict``), checkpoint promises enforced, ``precice-<participant>-iterations.log`` and
      ``precice-<participant>-convergence.log``.
    * ``exchange`` with ``initialize="true"`` (``requires_initial_data`` protocol) and
      ``substeps``; time interpolation of read data by ``waveform-degree`` (0: constant,
      >= 1: piecewise linear through the available samples).
    * written data is reset to zero after every ``advance`` (preCICE does this too: write
      every time step).
    * mappings ``nearest-neighbor`` (consistent and conservative, read and write), direct
      access (``api-access="true"`` + ``set_mesh_access_region``), watch points
      (``precice-<participant>-watchpoint-<name>.log``, nearest vertex).
    * the protocol checks of ``ParticipantImpl`` and the assertions of the Python bindings,
      with their messages: call order, initial data, ``advance(dt)`` bounds, checkpoint
      promises, write/read after the end or after ``finalize()``, unknown meshes and data,
      invalid vertex ids, mesh modification after ``initialize()``, a leftover address file,
      a configuration file that differs between the participants.
    * failure behaviour measured with preCICE 3.4.1: when a partner dies (killed, stopped,
      or exits) the surviving participant does **not** raise; it blocks in ``initialize``/
      ``advance`` forever. Whoever supervises it must kill it. (Real preCICE may first
      finish one or two more time windows with zero data before it blocks, and can even
      reach the end of the run that way if the partner died in the last windows; the double
      blocks at the first exchange that needs the dead partner. A supervisor should watch
      the solver processes themselves, not only the coupling.)

Not modelled
    * other mapping methods (``rbf-*``, ``nearest-projection``,
      ``linear-cell-interpolation``, ...) run as nearest-neighbor; just-in-time mappings,
      gradients, remeshing (``reset_mesh``), ``write_and_map_data`` and
      ``map_and_read_data`` raise.
    * acceleration (IQN, Aitken, constant under-relaxation): implicit coupling runs plain
      fixed-point iterations; higher waveform degrees interpolate linearly.
    * ``time-window-size method="first-participant"``, parallel participants
      (``solver_process_size > 1``), MPI communicators, mesh exports, profiling output.

Errors
    preCICE reports a misuse by throwing ``precice::Error`` (a ``std::runtime_error``),
    which the bindings turn into a Python ``RuntimeError``; the double raises
    :class:`PreciceError`, a ``RuntimeError`` subclass, with preCICE's message (and logs it
    as ``ERROR:``, like preCICE). Where the bindings check arguments themselves they raise
    ``AssertionError``/``TypeError``, and so does the double.

    Some misuses kill real pyprecice instead (measured with 3.4.1): the calls whose C++
    declaration lacks ``except +`` (``finalize`` twice, ``is_coupling_ongoing``,
    ``is_time_window_complete``, ``get_max_time_step_size``, ``requires_*`` at the wrong
    time, profiling sections) reach ``std::terminate`` and abort the process (SIGABRT, with
    "terminate called after throwing an instance of 'precice::Error'" and the message on
    stderr); ``advance`` before ``initialize``, and any call that needs a mesh or the
    coupling after ``finalize``, end in a segmentation fault. By default the double raises
    :class:`PreciceError` in these cases too, so tests can see them; with
    ``GYMPRECICE_FAKE_PRECICE_MISUSE=crash`` (or :data:`MISUSE` = "crash") it ends the
    process exactly as preCICE does, which is what a supervisor of a participant process
    should be tested against.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import json
import math
import os
import signal
import socket
import struct
import sys
import tempfile
import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NoReturn

import numpy as np

from gymprecice.errors import ConfigError
from gymprecice.precice_xml import (
    CouplingSchemeSpec,
    MappingSpec,
    PreciceConfig,
    load_precice_config,
    parse_tree,
)

__all__ = [
    "IS_FAKE",
    "MISUSE",
    "PRECICE_VERSION",
    "Participant",
    "PreciceError",
    "__version__",
    "get_version_information",
]

#: The preCICE release whose behaviour the double follows.
PRECICE_VERSION = "3.4.1"
#: Version of these "bindings", like ``precice.__version__`` of pyprecice.
__version__ = "3.4.0+gymprecice.fake"
#: Lets code (and logs) tell the double from the real library.
IS_FAKE = True

_VERSION_INFORMATION = (
    f"{PRECICE_VERSION};gymprecice fake_precice;PRECICE_FEATURE_MPI_COMMUNICATION=N;"
    "PRECICE_FEATURE_PETSC_MAPPING=N;PRECICE_FEATURE_GINKGO_MAPPING=N;"
    "PRECICE_FEATURE_PYTHON_ACTIONS=N;PRECICE_BINDINGS_C=N;PRECICE_BINDINGS_FORTRAN=N;"
    "CXX=none;CXXFLAGS=;LDFLAGS="
)

#: What a misuse that kills real preCICE does here: "raise" (default) raises
#: :class:`PreciceError`; "crash" ends the process the way preCICE 3.4.1 does (``abort()``
#: with libstdc++'s "terminate called ..." message, or a segmentation fault). Set it here or
#: with the environment variable ``GYMPRECICE_FAKE_PRECICE_MISUSE``.
MISUSE = os.environ.get("GYMPRECICE_FAKE_PRECICE_MISUSE", "raise")

_ADDRESS_FILE = "fake-precice.address"
_NUMERICAL_ZERO = 1e-14
_POLL_SECONDS = 0.002

#: Mappings that need edges/triangles of one mesh (requires_mesh_connectivity_for).
_CONNECTIVITY_METHODS = ("nearest-projection", "linear-cell-interpolation")

_INITIALIZE_DATA = "write-initial-data"
_WRITE_CHECKPOINT = "write-iteration-checkpoint"
_READ_CHECKPOINT = "read-iteration-checkpoint"

Key = tuple[str, str]  # (data name, mesh name)


class PreciceError(RuntimeError):
    """What preCICE's ``precice::Error`` becomes in Python: a ``RuntimeError`` with its message."""


def _fatal(kind: str, message: str) -> NoReturn:
    """A misuse that real pyprecice does not survive (measured with preCICE 3.4.1).

    ``kind`` is "abort" where the C++ call is not declared ``except +`` in the bindings (the
    ``precice::Error`` reaches ``std::terminate``) and "segfault" where preCICE dereferences
    state that does not exist yet (or anymore). With :data:`MISUSE` "raise" the double raises
    :class:`PreciceError` instead, which is what tests usually want to see.
    """
    if MISUSE != "crash":
        raise PreciceError(message)
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()
    if kind == "abort":
        os.write(
            2,
            b"terminate called after throwing an instance of 'precice::Error'\n  what():  "
            + message.encode()
            + b"\n",
        )
        os.abort()
    os.write(2, f"[fake_precice] Segmentation fault ({message})\n".encode())
    signal.signal(signal.SIGSEGV, signal.SIG_DFL)
    os.kill(os.getpid(), signal.SIGSEGV)
    _hang_forever()


def _edit_distance(a: str, b: str) -> int:
    row = list(range(len(b) + 1))
    for i, ca in enumerate(a, 1):
        prev, row[0] = row[0], i
        for j, cb in enumerate(b, 1):
            prev, row[j] = row[j], min(row[j] + 1, row[j - 1] + 1, prev + (ca != cb))
    return row[-1]


def _best_match(given: str, candidates: Iterable[str]) -> tuple[int, str] | None:
    scored = sorted((_edit_distance(given, c), c) for c in candidates)
    return scored[0] if scored else None


def get_version_information() -> bytes:
    """Like ``precice.get_version_information()``: preCICE's ``;``-separated build info, bytes."""
    return _VERSION_INFORMATION.encode()


# --------------------------------------------------------------------------- numerics


def _equals(a: float, b: float) -> bool:
    return abs(a - b) <= _NUMERICAL_ZERO


def _greater(a: float, b: float) -> bool:
    return a - b > _NUMERICAL_ZERO


def _greater_equals(a: float, b: float) -> bool:
    return a - b >= -_NUMERICAL_ZERO


def _num(value: float) -> str:
    """A number as preCICE's log (fmt) prints it: shortest round-trip form, no ``.0``."""
    text = repr(float(value))
    return text[:-2] if text.endswith(".0") else text


def _smaller(a: float, b: float) -> bool:
    return a - b < -_NUMERICAL_ZERO


class _Kahan:
    """Compensated sum, as preCICE keeps its time: many small steps add up exactly enough."""

    __slots__ = ("comp", "total")

    def __init__(self, total: float = 0.0, comp: float = 0.0) -> None:
        self.total = total
        self.comp = comp

    def add(self, value: float) -> None:
        y = value - self.comp
        t = self.total + y
        self.comp = (t - self.total) - y
        self.total = t

    def plus(self, value: float) -> float:
        other = _Kahan(self.total, self.comp)
        other.add(value)
        return other.total


class _Time:
    """Window start plus progress inside the window, with an optional end time."""

    __slots__ = ("max_time", "progress", "start")

    def __init__(self, max_time: float | None) -> None:
        self.max_time = max_time
        self.start = _Kahan()
        self.progress = _Kahan()

    def reset_to(self, t: float) -> None:
        self.start = _Kahan(t)
        self.progress = _Kahan()

    def progress_by(self, dt: float) -> None:
        self.progress.add(dt)

    def reset_progress(self) -> None:
        self.progress = _Kahan()

    def complete_window(self, size: float) -> None:
        if _equals(self.progress.total, size):
            self.start.add(size)
        else:  # the truncated last window, when max-time is not a multiple of the size
            self.start.add(self.progress.total)
        self.reset_progress()

    def time(self) -> float:
        return self.start.plus(self.progress.total)

    def until_time(self, t: float) -> float:
        return -(self.time() - t)

    def until_end(self) -> float:
        return math.inf if self.max_time is None else self.until_time(self.max_time)

    def until_window_end(self, size: float) -> float:
        until = -_Kahan(self.progress.total, self.progress.comp).plus(-size)
        return min(until, self.until_end())

    def reached_end(self) -> bool:
        return self.max_time is not None and _equals(self.until_time(self.max_time), 0.0)

    def reached_end_of_window(self, size: float) -> bool:
        return _equals(self.until_window_end(size), 0.0)


class _Waveform:
    """Time samples of one data on one mesh: what ``read_data`` interpolates in time."""

    __slots__ = ("times", "values")

    def __init__(self) -> None:
        self.times: list[float] = []
        self.values: list[np.ndarray] = []

    def __len__(self) -> int:
        return len(self.times)

    def set(self, t: float, values: np.ndarray) -> None:
        for i, ti in enumerate(self.times):
            if _equals(ti, t):
                self.values[i] = values
                return
            if ti > t:
                self.times.insert(i, t)
                self.values.insert(i, values)
                return
        self.times.append(t)
        self.values.append(values)

    def last(self) -> np.ndarray:
        return self.values[-1]

    def move(self) -> None:
        if len(self.times) > 1:
            self.times = self.times[-1:]
            self.values = self.values[-1:]

    def trim_before(self, t: float) -> None:
        keep = [i for i, ti in enumerate(self.times) if not _smaller(ti, t)]
        self.times = [self.times[i] for i in keep]
        self.values = [self.values[i] for i in keep]

    def trim_after(self, t: float) -> None:
        keep = [i for i, ti in enumerate(self.times) if not _greater(ti, t)]
        self.times = [self.times[i] for i in keep]
        self.values = [self.values[i] for i in keep]

    def sample(self, t: float, degree: int) -> np.ndarray:
        n = len(self.times)
        if min(degree, n - 1) == 0:
            if n == 1:
                return self.values[0]
            for ti, vi in zip(self.times, self.values):
                if _greater_equals(ti, t):
                    return vi
            return self.values[-1]
        for i, ti in enumerate(self.times):
            if _equals(ti, t):
                return self.values[i]
            if ti > t:
                if i == 0:
                    return self.values[0]
                t0 = self.times[i - 1]
                w = (t - t0) / (ti - t0)
                return (1.0 - w) * self.values[i - 1] + w * self.values[i]
        return self.values[-1]


def _nearest(query: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """Index of the nearest reference vertex for every query vertex (chunked brute force)."""
    index = np.zeros(len(query), dtype=np.int64)
    if len(reference) == 0 or len(query) == 0:
        return index
    chunk = max(1, 4_000_000 // max(1, len(reference)))
    for lo in range(0, len(query), chunk):
        part = query[lo : lo + chunk]
        d2 = ((part[:, None, :] - reference[None, :, :]) ** 2).sum(axis=2)
        index[lo : lo + chunk] = d2.argmin(axis=1)
    return index


class _Mapping:
    """A nearest-neighbour mapping between two meshes, computed once at ``initialize``."""

    def __init__(self, spec: MappingSpec, source: np.ndarray, target: np.ndarray) -> None:
        self.spec = spec
        self.consistent = spec.constraint != "conservative"
        self.n_source = len(source)
        self.n_target = len(target)
        if self.consistent:
            self.index = _nearest(target, source)
        else:
            self.index = _nearest(source, target)

    def apply(self, values: np.ndarray) -> np.ndarray:
        dim = values.shape[1]
        if self.consistent:
            if self.n_source == 0:
                return np.zeros((self.n_target, dim))
            return values[self.index]
        out = np.zeros((self.n_target, dim))
        if self.n_target:
            np.add.at(out, self.index, values)
        return out


# --------------------------------------------------------------------------- transport


def _hang_forever() -> NoReturn:
    """What preCICE does when a partner is gone: wait, never raise (measured with 3.4.1)."""
    while True:
        time.sleep(3600.0)


class _Channel:
    """One connected socket to one coupling partner, with length-prefixed messages.

    A message is a small JSON header (kind, a value, array descriptors) followed by the raw
    bytes of float64 arrays; nothing is unpickled, so nothing a peer sends can run code.
    """

    _PREFIX = struct.Struct("<QI")

    def __init__(self, sock: socket.socket, local: str, remote: str) -> None:
        self.sock = sock
        self.local = local
        self.remote = remote

    def send(self, kind: str, value: Any = None, arrays: Sequence[np.ndarray] = ()) -> None:
        blobs = [np.ascontiguousarray(a, dtype=np.float64) for a in arrays]
        header = json.dumps({"k": kind, "v": value, "a": [list(b.shape) for b in blobs]})
        head = header.encode()
        body_len = len(head) + sum(b.nbytes for b in blobs)
        parts = [self._PREFIX.pack(body_len, len(head)), head, *(b.tobytes() for b in blobs)]
        try:
            self.sock.sendall(b"".join(parts))
        except OSError:
            _hang_forever()

    def recv(self, kind: str) -> tuple[Any, list[np.ndarray]]:
        prefix = self._read(self._PREFIX.size)
        body_len, head_len = self._PREFIX.unpack(prefix)
        body = self._read(body_len)
        header = json.loads(bytes(body[:head_len]))
        if header["k"] != kind:
            raise PreciceError(
                f'Communication with participant "{self.remote}" is out of step: expected '
                f'"{kind}" but received "{header["k"]}". Both participants must run the '
                "same preCICE configuration with the same preCICE version."
            )
        arrays: list[np.ndarray] = []
        offset = head_len
        for shape in header["a"]:
            count = int(np.prod(shape)) if shape else 1
            nbytes = 8 * count
            arrays.append(
                np.frombuffer(body, dtype=np.float64, count=count, offset=offset).reshape(shape)
            )
            offset += nbytes
        return header["v"], arrays

    def _read(self, n: int) -> bytearray:
        buf = bytearray(n)
        view = memoryview(buf)
        got = 0
        while got < n:
            try:
                k = self.sock.recv_into(view[got:], n - got)
            except InterruptedError:
                continue
            except OSError:
                _hang_forever()
            if k == 0:  # the partner closed the connection (died or finalized early)
                _hang_forever()
            got += k
        return buf

    def close(self) -> None:
        with contextlib.suppress(OSError):
            self.sock.close()


def _short_socket_dir() -> Path:
    """A private (0700) directory whose path is short enough for ``AF_UNIX`` (108 bytes)."""
    base = tempfile.gettempdir()
    if len(base) > 60:
        base = "/tmp"
    return Path(tempfile.mkdtemp(prefix="fprc-", dir=base))


# --------------------------------------------------------------------------- configuration


@dataclass
class _Flow:
    """One exchanged data of a coupling scheme, from this participant's point of view."""

    data: str
    mesh: str
    partner: str
    initialize: bool
    substeps: bool

    @property
    def key(self) -> Key:
        return (self.data, self.mesh)


@dataclass
class _Measure:
    kind: str
    data: str
    mesh: str
    limit: float = 0.0
    abs_limit: float = 0.0
    rel_limit: float = 0.0
    suffices: bool = False
    strict: bool = False
    first_residual: float | None = None

    @property
    def header(self) -> str:
        abbreviation = {
            "absolute": "Abs",
            "relative": "Rel",
            "absolute-or-relative": "AbsOrRel",
            "residual-relative": "Drop",
        }.get(self.kind, self.kind)
        return f"Res{abbreviation}({self.mesh}:{self.data})"

    def measure(self, old: np.ndarray, new: np.ndarray) -> tuple[bool, float]:
        """(converged, residual as preCICE's convergence log reports it)."""
        diff = float(np.linalg.norm(new - old))
        norm = float(np.linalg.norm(new))
        relative = math.inf if _equals(norm, 0.0) else diff / norm
        if self.kind == "absolute":
            return diff <= self.limit, diff
        if self.kind == "relative":
            return diff <= norm * self.limit, relative
        if self.kind == "absolute-or-relative":
            return diff <= norm * self.rel_limit or diff <= self.abs_limit, relative
        if self.first_residual is None:  # residual-relative
            self.first_residual = diff
        drop = math.inf if _equals(self.first_residual, 0.0) else diff / self.first_residual
        return diff < self.first_residual * self.limit, drop


@dataclass
class _SchemeExtras:
    """What ``precice_xml`` does not keep of a coupling scheme, read here once."""

    substeps: list[bool | None] = field(default_factory=list)  # per exchange, None: default
    measures: list[_Measure] = field(default_factory=list)
    min_iterations: int = 1


def _truthy(value: str | None) -> bool:
    return (value or "").strip().lower() in ("1", "yes", "true", "on")


def _read_extras(path: Path) -> tuple[dict[str, str], bool, list[_SchemeExtras]]:
    """Root attributes, whether logging is on, and per-scheme details, in document order."""
    root = parse_tree(path).getroot()
    log_enabled = True
    extras: list[_SchemeExtras] = []
    for elem in root:
        if not isinstance(elem.tag, str):
            continue
        if elem.tag == "log":
            sinks = [s for s in elem if isinstance(s.tag, str) and s.tag == "sink"]
            switched_off = elem.get("enabled") is not None and not _truthy(elem.get("enabled"))
            no_sink_on = bool(sinks) and not any(_truthy(s.get("enabled", "1")) for s in sinks)
            log_enabled = log_enabled and not (switched_off or no_sink_on)
        elif elem.tag.startswith("coupling-scheme:"):
            extra = _SchemeExtras()
            for child in elem:
                if not isinstance(child.tag, str):
                    continue
                tag = child.tag
                if tag == "exchange":
                    raw = child.get("substeps")
                    extra.substeps.append(None if raw is None else _truthy(raw))
                elif tag == "min-iterations":
                    extra.min_iterations = int(float(child.get("value", "1")))
                elif tag.endswith("convergence-measure"):
                    kind = tag[: -len("-convergence-measure")]
                    extra.measures.append(
                        _Measure(
                            kind=kind,
                            data=child.get("data", ""),
                            mesh=child.get("mesh", ""),
                            limit=float(child.get("limit", "0") or 0),
                            abs_limit=float(child.get("abs-limit", "0") or 0),
                            rel_limit=float(child.get("rel-limit", "0") or 0),
                            suffices=_truthy(child.get("suffices")),
                            strict=_truthy(child.get("strict")),
                        )
                    )
            extras.append(extra)
    return dict(root.attrib), log_enabled, extras


# --------------------------------------------------------------------------- data store


class _Store:
    """Every waveform of one participant, keyed by (data, mesh), and what moves them."""

    def __init__(self, degrees: dict[str, int]) -> None:
        self.waves: dict[Key, _Waveform] = {}
        self.degrees = degrees

    def wave(self, key: Key) -> _Waveform:
        return self.waves.setdefault(key, _Waveform())

    def payload(self, flows: Iterable[_Flow]) -> tuple[list[Any], list[np.ndarray]]:
        entries: list[Any] = []
        arrays: list[np.ndarray] = []
        for flow in flows:
            wave = self.wave(flow.key)
            if flow.substeps:
                entries.append([flow.data, flow.mesh, list(wave.times)])
                arrays.extend(wave.values)
            else:
                entries.append([flow.data, flow.mesh, None])
                arrays.append(wave.last())
        return entries, arrays

    def deliver(
        self, flows: Iterable[_Flow], entries: list[Any], arrays: list[np.ndarray], at: float
    ) -> None:
        received: dict[Key, tuple[list[float] | None, list[np.ndarray]]] = {}
        pos = 0
        for data, mesh, times in entries:
            count = 1 if times is None else len(times)
            received[(data, mesh)] = (times, arrays[pos : pos + count])
            pos += count
        for flow in flows:
            times, values = received[flow.key]
            wave = self.wave(flow.key)
            if times is None:
                wave.set(at, values[0])
            else:
                if times:
                    wave.trim_after(times[0])
                for t, v in zip(times, values):
                    wave.set(t, v)

    def zero_at(self, flows: Iterable[_Flow], t: float, shapes: dict[Key, tuple[int, int]]) -> None:
        for flow in flows:
            self.wave(flow.key).set(t, np.zeros(shapes[flow.key]))

    def move(self, keys: Iterable[Key]) -> None:
        for key in keys:
            self.wave(key).move()


# --------------------------------------------------------------------------- coupling schemes


class _Scheme:
    """Time, actions and convergence of one coupling scheme, as one participant sees it.

    Subclasses only say who sends and receives what, in which order; that order is the
    one of preCICE's ``SerialCouplingScheme``, ``ParallelCouplingScheme`` and
    ``MultiCouplingScheme``, so both ends of every socket agree on every message.
    """

    def __init__(
        self, owner: _Coupling, spec: CouplingSchemeSpec, extra: _SchemeExtras, local: str
    ) -> None:
        self.owner = owner
        self.spec = spec
        self.local = local
        self.implicit = spec.implicit
        self.max_windows = spec.max_time_windows
        self.window_size = float(spec.time_window_size or 0.0)
        self.next_window_size = self.window_size
        self.time = _Time(spec.max_time)
        self.time_windows = 1
        self.iterations = 1
        self.total_iterations = 1
        self.min_iterations = extra.min_iterations if self.implicit else 1
        self.max_iterations = spec.max_iterations if self.implicit else None
        self.measures = [m for m in extra.measures] if self.implicit else []
        self.required: set[str] = set()
        self.fulfilled: set[str] = set()
        self.initialized = False
        self.window_complete = False
        self.converged = False
        self.does_first_step = True
        self.previous: dict[Key, np.ndarray] = {}
        self.iterations_log: Path | None = None
        self.convergence_log: Path | None = None
        self.send: list[_Flow] = []
        self.recv: list[_Flow] = []
        default_substeps = self.implicit
        for exchange, substeps in zip(spec.exchanges, extra.substeps):
            sub = default_substeps if substeps is None else substeps
            if exchange.from_participant == local:
                self.send.append(
                    _Flow(
                        exchange.data,
                        exchange.mesh,
                        exchange.to_participant,
                        exchange.initialize,
                        sub,
                    )
                )
            elif exchange.to_participant == local:
                self.recv.append(
                    _Flow(
                        exchange.data,
                        exchange.mesh,
                        exchange.from_participant,
                        exchange.initialize,
                        sub,
                    )
                )
        self.sends_initialized = any(f.initialize for f in self.send)
        self.receives_initialized = any(f.initialize for f in self.recv)
        if self.sends_initialized:
            self.required.add(_INITIALIZE_DATA)
        if self.implicit and not self.measures and self.max_iterations is None:
            raise PreciceError(
                "Not defining convergence measures without providing a maximum iteration limit "
                "is forbidden. Please define a convergence measure or set a maximum iteration "
                'limit using <max-iterations value="..." />.'
            )

    # -- bookkeeping shared with the compositional scheme

    @property
    def keys(self) -> list[Key]:
        return [f.key for f in (*self.send, *self.recv)]

    @property
    def partners(self) -> list[str]:
        return sorted({f.partner for f in (*self.send, *self.recv)} | self._extra_partners())

    def _extra_partners(self) -> set[str]:
        return set()

    def action_required(self, action: str) -> bool:
        return action in self.required

    def action_fulfilled(self, action: str) -> bool:
        return action in self.fulfilled

    def mark_fulfilled(self, action: str) -> None:
        self.fulfilled.add(action)

    def requires_substeps(self) -> bool:
        return any(f.substeps for f in self.send)

    def get_time(self) -> float:
        return self.time.time()

    def window_start(self) -> float:
        return self.time.start.total

    def is_ongoing(self) -> bool:
        windows_left = self.max_windows is None or self.max_windows >= self.time_windows
        return windows_left and not self.time.reached_end()

    def is_window_complete(self) -> bool:
        return self.window_complete

    def next_max(self) -> float:
        if not self.is_ongoing():
            return 0.0
        return self.time.until_window_end(self.window_size)

    def reached_end_of_window(self) -> bool:
        return self.time.reached_end_of_window(self.window_size)

    # -- the advance cycle (BaseCouplingScheme)

    def initialize(self) -> None:
        self.owner.store.zero_at(self.recv, 0.0, self.owner.shapes)
        self.time.reset_to(0.0)
        self.time_windows = 1
        for flow in self.send:
            if not len(self.owner.store.wave(flow.key)):
                raise PreciceError(
                    f"Data {flow.data} on mesh {flow.mesh} doesn't contain any samples while "
                    f"initializing a coupling scheme of participant {self.local}. There are two "
                    f"common configuration issues that may cause this. Either, make sure "
                    f"participant {self.local} specifies data {flow.data} to be written using "
                    f'tag <write-data mesh="{flow.mesh}" data="{flow.data}"/>. Or ensure '
                    f"participant {self.local} defines a mapping to mesh {flow.mesh} from a mesh "
                    f"using data {flow.data}."
                )
        if self.implicit:
            self.store_iteration()
            self.required.add(_WRITE_CHECKPOINT)
            self.iterations_log = Path(f"precice-{self.local}-iterations.log")
            self.iterations_log.write_text("  TimeWindow  TotalIterations  Iterations  Convergence")
            if not self.does_first_step:
                self.convergence_log = Path(f"precice-{self.local}-convergence.log")
                columns = ["TimeWindow", "Iteration", *(m.header for m in self.measures)]
                self.convergence_log.write_text("".join(f"  {c}" for c in columns))
        self.exchange_initial_data()
        self.initialized = True

    def add_computed_time(self, dt: float) -> bool:
        if not _greater_equals(self.next_max(), dt):
            raise PreciceError(
                f'The time step size given to preCICE in "advance" {dt!r} exceeds the maximum '
                f"allowed time step size {self.next_max()!r} in the remaining of this time "
                'window. Did you restrict your time step size, "dt = min(preciceDt, solverDt)"? '
                "For more information, consult the adapter example in the preCICE documentation."
            )
        self.time.progress_by(dt)
        return self.reached_end_of_window()

    def check_actions(self) -> None:
        if _INITIALIZE_DATA in self.required and _INITIALIZE_DATA not in self.fulfilled:
            raise PreciceError(
                'Data was not initialized. Did you forget to call "requiresWritingData()"?'
            )
        if _READ_CHECKPOINT in self.required and _READ_CHECKPOINT not in self.fulfilled:
            raise PreciceError(
                "The iteration checkpoint wasn't read. Did you forget to call "
                '"requiresReadingCheckpoint()"?'
            )
        if _WRITE_CHECKPOINT in self.required and _WRITE_CHECKPOINT not in self.fulfilled:
            raise PreciceError(
                "The iteration checkpoint wasn't written. Did you forget to call "
                '"requiresWritingCheckpoint()"?'
            )
        self.required.clear()
        self.fulfilled.clear()

    def first_exchange(self) -> None:
        self.check_actions()
        self.window_complete = False
        if self.reached_end_of_window():
            self.time_windows += 1
            self.exchange_first_data()

    def second_exchange(self) -> None:
        self.check_actions()
        if not self.reached_end_of_window():
            return
        self.exchange_second_data()
        if self.implicit:
            if not self.converged:
                self.required.add(_READ_CHECKPOINT)
                self.time_windows -= 1
                self.window_complete = False
            else:
                self._log_iterations()
                self.owner.p._log("Time window completed")
                self.window_complete = True
                if self.is_ongoing():
                    self.required.add(_WRITE_CHECKPOINT)
            self.total_iterations += 1
            self.iterations = 1 if self.converged else self.iterations + 1
        else:
            self.owner.p._log("Time window completed")
            self.window_complete = True
        if self.window_complete:
            self.time.complete_window(self.window_size)
        else:
            self.time.reset_progress()
        self.window_size = self.next_window_size

    def _log_iterations(self) -> None:
        if self.iterations_log is None:
            return
        limit_ok = self.max_iterations is None or self.iterations < self.max_iterations
        converged = int(self.iterations >= self.min_iterations and limit_ok)
        row = (
            f"\n{self.time_windows - 1:>6}  {self.total_iterations:>6}  "
            f"{self.iterations:>6}  {converged:>6}"
        )
        with self.iterations_log.open("a") as fh:
            fh.write(row)

    def do_implicit_step(self) -> None:
        self.converged = self.measure_convergence()
        if self.max_iterations is not None and self.iterations == self.max_iterations:
            self.converged = True
        if self.converged:
            for measure in self.measures:
                measure.first_residual = None

    def measure_convergence(self) -> bool:
        row = f"\n{self.time_windows - 1:>6}  {self.iterations:>6}"
        if not self.measures:
            self._log_convergence(row)
            return False
        all_converged, one_suffices, one_strict = True, False, False
        for measure in self.measures:
            key = (measure.data, measure.mesh)
            new = self.owner.store.wave(key).last()
            converged, residual = measure.measure(self.previous[key], new)
            row += f"  {residual:>15.8e}"
            if not converged:
                all_converged = False
                if measure.strict:
                    one_strict = True
                    if self.max_iterations is not None and self.iterations >= self.max_iterations:
                        raise PreciceError(
                            f'The strict convergence measure for data "{measure.data}" did not '
                            "converge within the maximum allowed iterations, which terminates "
                            "the simulation. To avoid this forced termination do not mark the "
                            "convergence measure as strict."
                        )
            elif measure.suffices:
                one_suffices = True
        self._log_convergence(row)
        enough = self.iterations >= self.min_iterations
        return enough and (all_converged or (one_suffices and not one_strict))

    def _log_convergence(self, row: str) -> None:
        if self.convergence_log is not None:
            with self.convergence_log.open("a") as fh:
                fh.write(row)

    def store_iteration(self) -> None:
        for key in self.keys:
            self.previous[key] = self.owner.store.wave(key).last().copy()

    def move_to_next_window(self) -> None:
        self.owner.store.move(self.keys)

    # -- communication helpers

    def send_data(self, partner: str, flows: list[_Flow]) -> None:
        entries, arrays = self.owner.store.payload(flows)
        self.owner.channel(partner).send("data", entries, arrays)

    def receive_data(self, partner: str, flows: list[_Flow], at: float | None = None) -> None:
        entries, arrays = self.owner.channel(partner).recv("data")
        self.owner.store.deliver(flows, entries, arrays, self.get_time() if at is None else at)

    def receive_data_for_window_end(self, partner: str, flows: list[_Flow]) -> None:
        self.receive_data(
            partner,
            flows,
            at=self.time.start.plus(self.time.progress.total + self.next_window_size),
        )

    def send_convergence(self, partner: str) -> None:
        self.owner.channel(partner).send("convergence", bool(self.converged))

    def receive_convergence(self, partner: str) -> None:
        value, _ = self.owner.channel(partner).recv("convergence")
        self.converged = bool(value)

    def zero_initialize(self, flows: list[_Flow]) -> None:
        self.owner.store.zero_at(flows, self.get_time(), self.owner.shapes)

    # -- to be provided by the concrete schemes

    def exchange_initial_data(self) -> None:
        raise NotImplementedError

    def exchange_first_data(self) -> None:
        raise NotImplementedError

    def exchange_second_data(self) -> None:
        raise NotImplementedError

    def state_text(self) -> str:
        """preCICE's ``printCouplingState``, logged after ``initialize`` and every ``advance``."""
        if not self.is_ongoing():
            return (
                f"Reached end at: final time-window: {self.time_windows - 1}, "
                f"final time: {_num(self.get_time())}"
            )
        text = ""
        if self.implicit:
            limits = [f"min: {self.min_iterations}"]
            if self.max_iterations is not None:
                limits.append(f"max: {self.max_iterations}")
            text += f"it {self.iterations} ({', '.join(limits)}), "
        text += f"time-window {self.time_windows}"
        if self.max_windows is not None:
            text += f" (max: {self.max_windows})"
        text += f", t {_num(self.get_time())}"
        if self.time.max_time is not None:
            text += f" (max: {_num(self.time.max_time)})"
        text += f", Dt {_num(self.window_size)}, max-dt {_num(self.next_max())}"
        return text


class _BiScheme(_Scheme):
    """``serial-*`` and ``parallel-*``: two participants, ``first`` and ``second``."""

    def __init__(
        self, owner: _Coupling, spec: CouplingSchemeSpec, extra: _SchemeExtras, local: str
    ) -> None:
        super().__init__(owner, spec, extra, local)
        self.serial = spec.serial
        self.does_first_step = spec.first == local
        self.partner = spec.second if self.does_first_step else spec.first

    def _extra_partners(self) -> set[str]:
        return {str(self.partner)}

    def exchange_initial_data(self) -> None:
        p = self.partner
        if self.serial:
            if self.does_first_step:
                if self.receives_initialized:
                    self.receive_data(p, self.recv)
                else:
                    self.zero_initialize(self.recv)
                if self.sends_initialized:
                    self.send_data(p, self.send)
            else:
                if self.sends_initialized:
                    self.send_data(p, self.send)
                if self.receives_initialized:
                    self.receive_data(p, self.recv)
                self.receive_data_for_window_end(p, self.recv)
        elif self.does_first_step:
            if self.sends_initialized:
                self.send_data(p, self.send)
            if self.receives_initialized:
                self.receive_data(p, self.recv)
            else:
                self.zero_initialize(self.recv)
        else:
            if self.receives_initialized:
                self.receive_data(p, self.recv)
            else:
                self.zero_initialize(self.recv)
            if self.sends_initialized:
                self.send_data(p, self.send)

    def exchange_first_data(self) -> None:
        p = self.partner
        if self.serial:
            if not self.implicit or self.does_first_step:
                self.send_data(p, self.send)
            else:
                self.do_implicit_step()
                self.send_convergence(p)
                self.send_data(p, self.send)
        elif self.does_first_step:
            self.send_data(p, self.send)
        else:
            self.receive_data(p, self.recv)

    def exchange_second_data(self) -> None:
        if self.serial:
            self._serial_second()
        else:
            self._parallel_second()

    def _serial_second(self) -> None:
        p = self.partner
        if not self.implicit:
            if self.does_first_step:
                self.receive_data(p, self.recv)
            self.move_to_next_window()
            if not self.does_first_step and self.is_ongoing():
                self.receive_data_for_window_end(p, self.recv)
            return
        if self.does_first_step:
            self.receive_convergence(p)
            self.receive_data(p, self.recv)
        if self.converged:
            self.move_to_next_window()
        self.store_iteration()
        if not self.does_first_step and (self.is_ongoing() or not self.converged):
            if self.converged:
                self.receive_data_for_window_end(p, self.recv)
            else:
                self.receive_data(p, self.recv)

    def _parallel_second(self) -> None:
        p = self.partner
        if not self.implicit:
            if self.does_first_step:
                self.receive_data(p, self.recv)
            else:
                self.send_data(p, self.send)
            self.move_to_next_window()
            return
        if self.does_first_step:
            self.receive_convergence(p)
            self.receive_data(p, self.recv)
        else:
            self.do_implicit_step()
            self.send_convergence(p)
            self.send_data(p, self.send)
        if self.converged:
            self.move_to_next_window()
        self.store_iteration()


class _MultiScheme(_Scheme):
    """``multi``: implicit, star-shaped around the ``control`` participant."""

    def __init__(
        self, owner: _Coupling, spec: CouplingSchemeSpec, extra: _SchemeExtras, local: str
    ) -> None:
        super().__init__(owner, spec, extra, local)
        if spec.control is None:
            raise PreciceError(
                "One controller per MultiCoupling needs to be defined. Please check the "
                "<participant name=... /> tags in the <coupling-scheme:... /> of your "
                "precice-config.xml. Make sure that at least one participant tag provides "
                'control="yes".'
            )
        self.controller = spec.control
        self.is_controller = spec.control == local
        self.does_first_step = not self.is_controller
        self.others = [p for p in spec.participants if p != local]
        if not self.is_controller:
            self.measures = []

    def _extra_partners(self) -> set[str]:
        return set(self.others) if self.is_controller else {self.controller}

    def _by_partner(self, flows: list[_Flow]) -> dict[str, list[_Flow]]:
        grouped: dict[str, list[_Flow]] = {}
        for flow in flows:
            grouped.setdefault(flow.partner, []).append(flow)
        return dict(sorted(grouped.items()))

    def exchange_initial_data(self) -> None:
        sends, recvs = self._by_partner(self.send), self._by_partner(self.recv)
        if self.is_controller:
            self._initial_receive(recvs)
            self._initial_send(sends)
        else:
            self._initial_send(sends)
            self._initial_receive(recvs)

    def _initial_send(self, sends: dict[str, list[_Flow]]) -> None:
        for partner, flows in sends.items():
            if any(f.initialize for f in flows):
                self.send_data(partner, flows)

    def _initial_receive(self, recvs: dict[str, list[_Flow]]) -> None:
        for partner, flows in recvs.items():
            if any(f.initialize for f in flows):
                self.receive_data(partner, flows)
            else:
                self.zero_initialize(flows)

    def exchange_first_data(self) -> None:
        if self.is_controller:
            for partner, flows in self._by_partner(self.recv).items():
                self.receive_data(partner, flows)
        else:
            for partner, flows in self._by_partner(self.send).items():
                self.send_data(partner, flows)

    def exchange_second_data(self) -> None:
        if not self.is_controller:
            self.receive_convergence(self.controller)
            for partner, flows in self._by_partner(self.recv).items():
                self.receive_data(partner, flows)
        else:
            self.do_implicit_step()
            for partner in sorted(self.others):
                self.send_convergence(partner)
            for partner, flows in self._by_partner(self.send).items():
                self.send_data(partner, flows)
        if self.converged:
            self.move_to_next_window()
        self.store_iteration()


class _Composite:
    """Several schemes of one participant: explicit ones plus at most one implicit one.

    Like preCICE's ``CompositionalCouplingScheme``: while the implicit scheme iterates, the
    explicit schemes are on hold; they exchange once the implicit window has converged.
    """

    def __init__(self, schemes: list[_Scheme]) -> None:
        self.explicit = [s for s in schemes if not s.implicit]
        implicit = [s for s in schemes if s.implicit]
        self.implicit_scheme = implicit[0] if implicit else None
        self.on_hold = False
        self.active: list[_Scheme] = []

    @property
    def implicit(self) -> bool:
        return self.implicit_scheme is not None

    @property
    def schemes(self) -> list[_Scheme]:
        return [*self.explicit, *([self.implicit_scheme] if self.implicit_scheme else [])]

    def _active_or_all(self) -> list[_Scheme]:
        return self.active or self.schemes

    def initialize(self) -> None:
        for scheme in self.schemes:
            scheme.initialize()
            self.active.append(scheme)

    def add_computed_time(self, dt: float) -> bool:
        if self.implicit_scheme is None:
            at_end = False
            for scheme in self.explicit:
                at_end |= scheme.add_computed_time(dt)
            return at_end
        implicit_at_end = self.implicit_scheme.add_computed_time(dt)
        if self.on_hold:
            return implicit_at_end
        explicit_at_end = False
        for scheme in self.explicit:
            explicit_at_end |= scheme.add_computed_time(dt)
        if implicit_at_end:
            self.on_hold = True
            self._update_active()
        return implicit_at_end or explicit_at_end

    def first_exchange(self) -> None:
        if self.implicit_scheme is None:
            for scheme in self.explicit:
                scheme.first_exchange()
            return
        self.implicit_scheme.first_exchange()
        if self.on_hold:
            return
        for scheme in self.explicit:
            scheme.first_exchange()

    def second_exchange(self) -> None:
        if self.implicit_scheme is None:
            for scheme in self.explicit:
                scheme.second_exchange()
            return
        self.implicit_scheme.second_exchange()
        if not self.explicit:
            self.on_hold = False
            self._update_active()
            return
        if self.implicit_scheme.get_time() < self.explicit[0].get_time():
            return  # still iterating: the explicit schemes stay on hold
        for scheme in self.explicit:
            scheme.first_exchange()
        for scheme in self.explicit:
            scheme.second_exchange()
        self.on_hold = False
        self._update_active()

    def _update_active(self) -> None:
        if self.implicit_scheme is None:
            return
        self.active = [self.implicit_scheme]
        if not self.on_hold:
            self.active.extend(self.explicit)

    def is_ongoing(self) -> bool:
        if self.implicit_scheme is not None:
            return self.implicit_scheme.is_ongoing()
        return self.explicit[0].is_ongoing()

    def get_time(self) -> float:
        if self.implicit_scheme is not None:
            return self.implicit_scheme.get_time()
        return self.explicit[0].get_time()

    def window_start(self) -> float:
        return min(s.window_start() for s in self.schemes)

    def next_max(self) -> float:
        return min(s.next_max() for s in self.active)

    def is_window_complete(self) -> bool:
        return any(s.is_window_complete() for s in self.active)

    def action_required(self, action: str) -> bool:
        return any(s.action_required(action) for s in self._active_or_all())

    def action_fulfilled(self, action: str) -> bool:
        return any(s.action_fulfilled(action) for s in self._active_or_all())

    def mark_fulfilled(self, action: str) -> None:
        for scheme in self._active_or_all():
            if scheme.action_required(action):
                scheme.mark_fulfilled(action)

    def requires_substeps(self) -> bool:
        return any(s.requires_substeps() for s in self.schemes)

    def state_text(self) -> str:
        if len(self.schemes) == 1:
            return self.schemes[0].state_text()
        return "; ".join(
            f"partner: {' & '.join(s.partners)}, {s.state_text()}" for s in self.schemes
        )


# --------------------------------------------------------------------------- the participant


@dataclass
class _Mesh:
    name: str
    dims: int
    provided: bool
    source: str | None = None  # participant a received mesh comes from
    api_access: bool = False
    chunks: list[np.ndarray] = field(default_factory=list)
    coords: np.ndarray | None = None
    region: np.ndarray | None = None

    @property
    def n(self) -> int:
        return len(self.coordinates)

    @property
    def coordinates(self) -> np.ndarray:
        if self.coords is None:
            self.coords = np.concatenate(self.chunks) if self.chunks else np.zeros((0, self.dims))
        return self.coords

    def add(self, positions: np.ndarray) -> np.ndarray:
        start = self.n
        self.chunks = [self.coordinates, positions.reshape(-1, self.dims).astype(np.float64)]
        self.coords = None
        return np.arange(start, start + len(positions), dtype=np.int32)

    def in_region(self) -> np.ndarray:
        """Indices of the vertices inside the access region (all without a region)."""
        coords = self.coordinates
        if self.region is None:
            return np.arange(len(coords))
        lo, hi = self.region[0::2], self.region[1::2]
        inside = np.all((coords >= lo) & (coords <= hi), axis=1)
        return np.nonzero(inside)[0]


class _Coupling:
    """Everything ``initialize`` builds: channels, received meshes, mappings, schemes."""

    def __init__(self, participant: Participant) -> None:
        self.p = participant
        self.store = _Store(participant._degrees)
        self.channels: dict[str, _Channel] = {}
        self.shapes: dict[Key, tuple[int, int]] = {}

    def channel(self, partner: str) -> _Channel:
        try:
            return self.channels[partner]
        except KeyError:
            raise PreciceError(
                f'There is no m2n communication between participants "{self.p._name}" and '
                f'"{partner}", but they exchange data. Please add an <m2n:sockets '
                f'acceptor="{self.p._name}" connector="{partner}" /> tag to the preCICE '
                "configuration."
            ) from None


def _convert(value: Any) -> str:
    """The bindings' ``convert``: str or bytes, anything else is a ``TypeError``."""
    if type(value) is bytes:
        return value.decode()
    if type(value) is str:
        return value
    raise TypeError("Could not convert.")


def _check_array_like(argument: Any, argument_name: str, function_name: str) -> None:
    try:
        argument.__len__  # noqa: B018
        argument.__getitem__  # noqa: B018
    except AttributeError:
        raise TypeError(
            f"{function_name} requires array_like input for {argument_name}, but was provided "
            f"the following input type: {type(argument)}"
        ) from None


def _ids(vertex_ids: Any) -> np.ndarray:
    ids = np.asarray(vertex_ids)
    if ids.size and ids.dtype.kind not in "iu":
        raise TypeError("an integer is required")
    return ids.astype(np.int64, copy=False).reshape(-1)


class Participant:
    """Drop-in for ``precice.Participant`` (pyprecice v3); see the module docstring.

    One object is one participant of one coupled run. It is not thread-safe, and like the
    real library it is meant to live in its own process.
    """

    def __init__(
        self,
        participant_name: str,
        configuration_file_name: str,
        solver_process_index: int,
        solver_process_size: int,
        communicator: Any = None,
    ) -> None:
        self._state = "constructed"
        self._coupling: _Coupling | None = None
        self._name = _convert(participant_name)
        config_file = _convert(configuration_file_name)
        if not self._name:
            raise PreciceError(
                "This participant's name is an empty string. When constructing a preCICE "
                "interface you need to pass the name of the participant as first argument to "
                "the constructor."
            )
        rank, size = int(solver_process_index), int(solver_process_size)
        if rank < 0:
            raise PreciceError(
                f"The solver process index needs to be a non-negative number, not: {rank}. "
                "Please check the value given when constructing a preCICE interface."
            )
        if size < 1:
            raise PreciceError(
                f"The solver process size needs to be a positive number, not: {size}. "
                "Please check the value given when constructing a preCICE interface."
            )
        if rank >= size:
            raise PreciceError(
                f"The solver process index, currently: {rank}  needs to be smaller than the "
                f"solver process size, currently: {size}. Please check the values given when "
                "constructing a preCICE interface."
            )
        if size > 1:
            raise PreciceError(
                "gymprecice's fake_precice runs serial participants only "
                f"(solver_process_size={size}); use real preCICE for parallel participants."
            )
        self._config_path = Path(config_file)
        try:
            self._cfg: PreciceConfig = load_precice_config(self._config_path)
            root_attrs, self._log_enabled, extras = _read_extras(self._config_path)
            self._config_hash = hashlib.sha256(self._config_path.read_bytes()).hexdigest()
        except ConfigError as exc:
            raise PreciceError(str(exc)) from exc
        self._experimental = _truthy(root_attrs.get("experimental"))
        self._allow_remeshing = _truthy(root_attrs.get("allow-remeshing"))
        self._log(f"This is preCICE version {PRECICE_VERSION} (gymprecice fake_precice)")
        self._log(f'Configuring preCICE with configuration "{config_file}"')
        self._log(f'I am participant "{self._name}"')
        if len(self._cfg.participants) < 2:
            raise PreciceError(
                "In the preCICE configuration, only one participant is defined. One participant "
                "makes no coupled simulation. Please add at least another one."
            )
        if self._name not in self._cfg.participants:
            raise PreciceError(
                "This participant's name, which was specified in the constructor of the preCICE "
                f'interface as "{self._name}", is not defined in the preCICE configuration. '
                "Please double-check the correct spelling."
            )
        self._spec = self._cfg.participants[self._name]
        self._degrees = {
            name: (1 if d.waveform_degree is None else d.waveform_degree)
            for name, d in self._cfg.data.items()
        }
        self._meshes: dict[str, _Mesh] = {}
        for name in self._spec.provided_meshes:
            self._meshes[name] = _Mesh(name, self._cfg.meshes[name].dimensions, provided=True)
        for name, source in self._spec.received_meshes.items():
            self._meshes[name] = _Mesh(
                name,
                self._cfg.meshes[name].dimensions,
                provided=False,
                source=source,
                api_access=name in self._spec.api_access_meshes,
            )
        self._writes: set[Key] = set(self._spec.write_data)
        self._reads: set[Key] = set(self._spec.read_data)
        self._buffers: dict[Key, np.ndarray] = {}
        self._user_events: list[str] = []
        self._advance_calls = 0
        self._check_watch_points()
        self._scheme = self._build_schemes(extras)
        self._open_watch_point_logs()

    # ----------------------------------------------------------------- construction helpers

    def _log(self, message: str) -> None:
        out = sys.stdout
        if self._log_enabled and out is not None:
            with contextlib.suppress(OSError, ValueError):
                out.write(f"---[precice]  {message}\n")
                out.flush()

    def _build_schemes(self, extras: list[_SchemeExtras]) -> _Composite:
        owner = _Coupling(self)
        self._coupling = owner
        schemes: list[_Scheme] = []
        for spec, extra in zip(self._cfg.coupling_schemes, extras):
            if self._name not in spec.participants:
                continue
            if spec.time_window_method != "fixed" or not spec.time_window_size:
                raise PreciceError(
                    f'gymprecice\'s fake_precice models <time-window-size value="..." /> with a '
                    f'fixed size only, not method="{spec.time_window_method}" '
                    f"(coupling scheme in line {spec.line})."
                )
            if spec.max_time is None and spec.max_time_windows is None:
                raise PreciceError(
                    "At least one termination condition is required for the coupling scheme of "
                    f'type "{spec.kind}". Please add a <max-time value="..."/> or '
                    f'<max-time-windows value="..."/> tag inside your <coupling-scheme:'
                    f"{spec.kind}> configuration."
                )
            kind = spec.kind
            scheme: _Scheme
            if kind == "multi":
                scheme = _MultiScheme(owner, spec, extra, self._name)
            elif kind in (
                "serial-explicit",
                "parallel-explicit",
                "serial-implicit",
                "parallel-implicit",
            ):
                scheme = _BiScheme(owner, spec, extra, self._name)
            else:
                raise PreciceError(f'Unknown coupling scheme "coupling-scheme:{kind}".')
            if scheme.implicit and any(s.implicit for s in schemes):
                raise PreciceError(
                    "You attempted to define a second implicit coupling-scheme for the "
                    f'participant "{self._name}", which is not allowed. Please use a multi '
                    "coupling-scheme for true implicit coupling of multiple participants."
                )
            for measure in scheme.measures:
                if (measure.data, measure.mesh) not in scheme.keys:
                    raise PreciceError(
                        f'Data "{measure.data}" on mesh "{measure.mesh}" is not exchanged in '
                        "this coupling scheme, so it cannot have a convergence measure."
                    )
            schemes.append(scheme)
        if not schemes:
            raise PreciceError(
                f'No coupling scheme defined for participant "{self._name}". Please make sure to '
                "provide at least one <coupling-scheme:TYPE> in your precice-config.xml that "
                "couples this participant using the <participants .../> tag."
            )
        return _Composite(schemes)

    def _check_watch_points(self) -> None:
        for wp in self._spec.watch_points:
            mesh = self._meshes.get(wp.mesh)
            if mesh is None or not mesh.provided:
                raise PreciceError(
                    f'Participant "{self._name}" defines watchpoint "{wp.name}" for the received '
                    f'mesh "{wp.mesh}", which is not allowed. Please move the watchpoint '
                    f'definition to the participant providing mesh "{wp.mesh}".'
                )

    def _open_watch_point_logs(self) -> None:
        for wp in self._spec.watch_points:
            mesh = self._cfg.meshes[wp.mesh]
            columns = ["Time", *(f"Coordinate{i}" for i in range(mesh.dimensions))]
            for data in mesh.data:
                if self._cfg.data[data].kind == "scalar":
                    columns.append(data)
                else:
                    columns.extend(f"{data}{i}" for i in range(mesh.dimensions))
            header = "".join(f"  {c}" for c in columns)
            Path(f"precice-{self._name}-watchpoint-{wp.name}.log").write_text(header)

    def _export_watch_points(self, t: float) -> None:
        for wp in self._spec.watch_points:
            mesh = self._meshes[wp.mesh]
            if mesh.n == 0:
                continue
            point = np.asarray(wp.coordinate, dtype=float)[: mesh.dims]
            vertex = int(_nearest(point[None, :], mesh.coordinates)[0])
            values = [t, *mesh.coordinates[vertex]]
            for data in self._cfg.meshes[wp.mesh].data:
                dim = self._data_dims(data, wp.mesh)
                wave = self._coupling.store.wave((data, wp.mesh)) if self._coupling else None
                if wave is not None and len(wave):
                    values.extend(wave.sample(t, self._degrees[data])[vertex][:dim])
                else:
                    values.extend([0.0] * dim)
            row = "\n" + "  ".join(f"{v:>15.8e}" for v in values)
            with open(f"precice-{self._name}-watchpoint-{wp.name}.log", "a") as fh:
                fh.write(row)

    def _data_dims(self, data: str, mesh: str) -> int:
        return 1 if self._cfg.data[data].kind == "scalar" else self._cfg.meshes[mesh].dimensions

    # ----------------------------------------------------------------- validation (macros)

    def _hint_for_mesh(self, mesh: str) -> str:
        names = sorted(self._meshes)
        if len(names) == 1:
            return f' This participant only knows mesh "{names[0]}".'
        best = _best_match(mesh, names)
        if best is not None and best[0] < 3:
            return f' Did you mean mesh "{best[1]}"?'
        return f" Available meshes are: {', '.join(names)}"

    def _validate_mesh(self, mesh: str) -> _Mesh:
        try:
            return self._meshes[mesh]
        except KeyError:
            raise PreciceError(
                f'The mesh named "{mesh}" is unknown to preCICE.{self._hint_for_mesh(mesh)}'
            ) from None

    def _validate_data(self, mesh: str, data: str) -> None:
        self._validate_mesh(mesh)
        known = self._cfg.meshes[mesh].data
        if data not in known:
            others = [m for m in sorted(self._meshes) if data in self._cfg.meshes[m].data]
            best = _best_match(data, known)
            if others:
                hint = f' Did you mean the data of mesh "{others[0]}"?'
            elif len(known) == 1:
                hint = f' This mesh only knows data "{known[0]}".'
            elif best is not None and best[0] < 3:
                hint = f' Did you mean data "{best[1]}"?'
            else:
                hint = f" Available data are: {', '.join(known)}"
            raise PreciceError(
                f'The given data "{data}" is unknown to preCICE mesh "{mesh}".{hint}'
            )

    def _require_mesh_modify(self, mesh_name: str) -> _Mesh:
        mesh = self._validate_mesh(mesh_name)
        if not mesh.provided:
            raise PreciceError(
                f'This participant does not provide Mesh "{mesh_name}", but attempted to modify '
                f'it. Please add a provide-mesh tag as follows <provide-mesh name="{mesh_name}" />.'
            )
        if self._state != "constructed":
            raise PreciceError(
                f'This participant attempted to modify the Mesh "{mesh_name}" while locked. '
                "Mesh modification is only allowed before calling initialize()."
            )
        return mesh

    def _require_data_access(self, mesh_name: str, data: str, write: bool) -> _Mesh:
        mesh = self._validate_mesh(mesh_name)
        if not (mesh.provided or mesh.api_access):
            raise PreciceError(
                f'This participant does not provide Mesh "{mesh_name}" nor does it enable direct '
                "access to it. To provide the mesh add a provide-mesh tag as follows "
                f'<provide-mesh name="{mesh_name}" />. To enable direct access to the mesh please '
                f'add a receive-mesh tag as follows <receive-mesh name="{mesh_name}" from="..." '
                'api-access="true" />, or modify an existing one. '
            )
        self._validate_data(mesh_name, data)
        allowed = self._writes if write else self._reads
        if (data, mesh_name) not in allowed:
            verb, tag = ("write", "write-data") if write else ("read", "read-data")
            raise PreciceError(
                f'This participant does not use data "{data}" via mesh "{mesh_name}", but '
                f"attempted to {verb} it. Please extend the configuration of participant "
                f'"{self._name}" by defining <{tag} mesh="{mesh_name}" name="{data}" /> or check '
                "if the data is defined on this mesh."
            )
        return mesh

    def _require_direct_access(
        self, mesh_name: str, function: str, what: str, preposition: str = "from mesh"
    ) -> _Mesh:
        mesh = self._validate_mesh(mesh_name)
        if mesh.provided or not mesh.api_access:
            raise PreciceError(
                f'This participant attempteded to {what} (via "{function}") {preposition} '
                f'"{mesh_name}", but mesh "{mesh_name}" is either not a received mesh or its api '
                f"access was not enabled in the configuration. {function}(...) is only valid for "
                f'(<receive-mesh name="{mesh_name}" ... api-access="true"/>).'
            )
        return mesh

    def _require_experimental(self, function: str) -> None:
        if not self._experimental:
            raise PreciceError(
                f'You called the API function "{function}", which is part of the experimental '
                "API. You may unlock the full API by specifying <precice-configuration "
                'experimental="true" ... > in the configuration. Please be aware that '
                "experimental features may change in any future version (even minor or bugfix)."
            )

    def _check_ongoing(self) -> bool:
        return self._scheme.is_ongoing()

    def _alive(self, call: str) -> None:
        """After ``finalize()`` preCICE has dropped its state: calls that use it crash."""
        if self._state == "finalized":
            _fatal("segfault", f"{call} cannot be called after finalize().")

    # ----------------------------------------------------------------- steering

    def initialize(self) -> None:
        """Connect to the partners, exchange meshes and initial data; blocks until they do."""
        if self._state == "finalized":
            raise PreciceError("initialize() cannot be called after finalize().")
        if self._state == "initialized":
            raise PreciceError("initialize() may only be called once.")
        scheme = self._scheme
        if scheme.action_required(_INITIALIZE_DATA) and not scheme.action_fulfilled(
            _INITIALIZE_DATA
        ):
            raise PreciceError(
                "Initial data has to be written to preCICE before calling initialize(). After "
                "defining your mesh, call requiresInitialData() to check if the participant is "
                "required to write initial data using the writeData() function."
            )
        if self._user_events:
            raise PreciceError(
                "There are unstopped user defined events. Please stop them using "
                "stopLastProfilingSection() before calling initialize()."
            )
        coupling = self._coupling
        assert coupling is not None
        self._log("Setting up primary communication to coupling partner/s")
        self._connect(coupling)
        self._log("Primary ranks are connected")
        self._exchange_meshes(coupling)
        for mesh in self._meshes.values():
            if mesh.api_access and mesh.region is None and not self._mapped(mesh.name):
                raise PreciceError(
                    "You are running this participant in serial mode and the bounding box on "
                    f'mesh "{mesh.name}", is empty. Did you call setMeshAccessRegion with valid '
                    "data?"
                )
        for (data, mesh_name), buf in list(self._buffers.items()):
            self._buffers[(data, mesh_name)] = self._resized(buf, data, mesh_name)
        for mesh in self._meshes.values():
            for data in self._cfg.meshes[mesh.name].data:
                coupling.shapes[(data, mesh.name)] = (mesh.n, self._data_dims(data, mesh.name))
        self._build_mappings(coupling)
        for key in self._writes:
            coupling.store.wave(key).set(0.0, self._buffer(*key).copy())
        self._map_written(after=None)
        scheme.initialize()
        self._map_read()
        self._export_watch_points(0.0)
        self._reset_written()
        self._state = "initialized"
        self._log(scheme.state_text())

    def advance(self, computed_timestep_length: float) -> None:
        """Tell preCICE the solver computed ``dt``; at a window end, exchange data (blocks)."""
        dt = float(computed_timestep_length)
        if self._user_events:
            raise PreciceError(
                "There are unstopped user defined events. Please stop them using "
                "stopLastProfilingSection() before calling advance()."
            )
        if self._state == "constructed":
            _fatal("segfault", "initialize() has to be called before advance().")
        if self._state == "finalized":
            _fatal("segfault", "advance() cannot be called after finalize().")
        scheme = self._scheme
        if not scheme.is_ongoing():
            raise PreciceError("advance() cannot be called when isCouplingOngoing() returns false.")
        if not math.isfinite(dt):
            raise PreciceError("advance() cannot be called with an infinite time step size.")
        if _equals(dt, 0.0):
            raise PreciceError("advance() cannot be called with a time step size of 0.")
        if dt < 0.0:
            raise PreciceError(f"advance() cannot be called with a negative time step size {dt!r}.")
        self._advance_calls += 1
        at_window_end = scheme.add_computed_time(dt)
        stepped_to = scheme.get_time()
        window_start = scheme.window_start()
        coupling = self._coupling
        assert coupling is not None
        if at_window_end or scheme.requires_substeps():
            for key in self._writes:
                coupling.store.wave(key).set(stepped_to, self._buffer(*key).copy())
        self._reset_written()
        if at_window_end:
            self._map_written(after=window_start)
        scheme.first_exchange()
        scheme.second_exchange()
        if at_window_end:
            after = scheme.get_time()
            complete = scheme.is_window_complete()
            if complete:
                start = scheme.window_start()
                for wave in coupling.store.waves.values():
                    wave.trim_before(start)
            else:
                for key in self._writes:
                    coupling.store.wave(key).trim_after(after)
                for mapping, data in self._write_maps:
                    coupling.store.wave((data, mapping.spec.to_mesh)).trim_after(after)
            self._map_read()
            if complete:
                self._export_watch_points(after)
        self._log(scheme.state_text())

    def finalize(self) -> None:
        """Close the connections; the partners are not waited for (like preCICE's default)."""
        if self._state == "finalized":
            _fatal("abort", "finalize() may only be called once.")
        self._user_events.clear()
        if self._state == "initialized" and self._coupling is not None:
            self._log("Close communication channels")
            for ch in self._coupling.channels.values():
                ch.close()
        self._state = "finalized"

    def __del__(self) -> None:
        # Like the real destructor: an unfinalized participant still closes its connections.
        coupling = getattr(self, "_coupling", None)
        if coupling is not None:
            with contextlib.suppress(Exception):
                for ch in coupling.channels.values():
                    ch.close()

    # ----------------------------------------------------------------- status queries

    def get_mesh_dimensions(self, mesh_name: str) -> int:
        self._alive("getMeshDimensions()")
        return self._validate_mesh(_convert(mesh_name)).dims

    def get_data_dimensions(self, mesh_name: str, data_name: str) -> int:
        self._alive("getDataDimensions()")
        mesh, data = _convert(mesh_name), _convert(data_name)
        self._validate_data(mesh, data)
        return self._data_dims(data, mesh)

    def is_coupling_ongoing(self) -> bool:
        if self._state == "finalized":
            _fatal("abort", "isCouplingOngoing() cannot be called after finalize().")
        if self._state != "initialized":
            _fatal(
                "abort",
                "initialize() has to be called before isCouplingOngoing() can be evaluated.",
            )
        return self._scheme.is_ongoing()

    def is_time_window_complete(self) -> bool:
        if self._state == "constructed":
            _fatal("abort", "initialize() has to be called before isTimeWindowComplete().")
        if self._state == "finalized":
            _fatal("abort", "isTimeWindowComplete() cannot be called after finalize().")
        return self._scheme.is_window_complete()

    def get_max_time_step_size(self) -> float:
        if self._state == "finalized":
            _fatal("abort", "getMaxTimeStepSize() cannot be called after finalize().")
        if self._state != "initialized":
            _fatal(
                "abort",
                "initialize() has to be called before getMaxTimeStepSize() can be evaluated.",
            )
        return float(self._scheme.next_max())

    def requires_initial_data(self) -> bool:
        if self._state != "constructed":
            _fatal("abort", "requiresInitialData() has to be called before initialize().")
        required = self._scheme.action_required(_INITIALIZE_DATA)
        if required:
            self._scheme.mark_fulfilled(_INITIALIZE_DATA)
        return required

    def requires_writing_checkpoint(self) -> bool:
        if self._state != "initialized":
            _fatal("abort", "initialize() has to be called before requiresWritingCheckpoint().")
        required = self._scheme.action_required(_WRITE_CHECKPOINT)
        if required:
            self._scheme.mark_fulfilled(_WRITE_CHECKPOINT)
        return required

    def requires_reading_checkpoint(self) -> bool:
        if self._state != "initialized":
            _fatal("abort", "initialize() has to be called before requiresReadingCheckpoint().")
        required = self._scheme.action_required(_READ_CHECKPOINT)
        if required:
            self._scheme.mark_fulfilled(_READ_CHECKPOINT)
        return required

    # ----------------------------------------------------------------- mesh access

    def requires_mesh_connectivity_for(self, mesh_name: str) -> bool:
        """True where a projection-based mapping would need edges/triangles of this mesh."""
        self._alive("requiresMeshConnectivityFor()")
        mesh = _convert(mesh_name)
        self._validate_mesh(mesh)
        for participant in self._cfg.participants.values():
            for mapping in participant.mappings:
                if mapping.method not in _CONNECTIVITY_METHODS:
                    continue
                conservative = mapping.constraint == "conservative"
                if (mapping.to_mesh if conservative else mapping.from_mesh) == mesh:
                    return True
        return False

    def set_mesh_vertex(self, mesh_name: str, position: Any) -> int:
        _check_array_like(position, "position", "set_mesh_vertex")
        self._alive("setMeshVertex()")
        name = _convert(mesh_name)
        if len(position) > 0:
            dimensions = len(position)
            expected = self.get_mesh_dimensions(name)
            assert dimensions == expected, (
                "Dimensions of vertex coordinate in set_mesh_vertex does not match with "
                "dimensions in problem definition. Provided dimensions: "
                f"{dimensions}, expected dimensions: {expected}"
            )
        mesh = self._require_mesh_modify(name)
        pos = np.asarray(position, dtype=np.float64).reshape(-1)
        if len(pos) != mesh.dims:
            raise PreciceError(
                f'Cannot set vertex for mesh "{name}". Expected {mesh.dims} position components '
                f"but found {len(pos)}."
            )
        return int(mesh.add(pos)[0])

    def get_mesh_vertex_size(self, mesh_name: str) -> int:
        self._alive("getMeshVertexSize()")
        name = _convert(mesh_name)
        mesh = self._validate_mesh(name)
        if self._state != "initialized" and not mesh.provided:
            raise PreciceError(
                "initialize() has to be called before accessing data of the received mesh "
                f'"{name}" on participant "{self._name}".'
            )
        if not mesh.provided and mesh.api_access:
            return len(mesh.in_region())
        return mesh.n

    def set_mesh_vertices(self, mesh_name: str, positions: Any) -> np.ndarray:
        _check_array_like(positions, "positions", "set_mesh_vertices")
        self._alive("setMeshVertices()")
        name = _convert(mesh_name)
        if not isinstance(positions, np.ndarray):
            positions = np.asarray(positions)
        if len(positions) > 0:
            _size, dimensions = positions.shape
            expected = self.get_mesh_dimensions(name)
            assert dimensions == expected, (
                "Dimensions of vertex coordinates in set_mesh_vertices does not match with "
                f"dimensions in problem definition. Provided dimensions: {dimensions}, expected "
                f"dimensions: {expected}"
            )
        else:
            self.get_mesh_dimensions(name)
        mesh = self._require_mesh_modify(name)
        return mesh.add(np.asarray(positions, dtype=np.float64).reshape(-1, mesh.dims))

    def _connectivity(self, mesh_name: str, vertex_ids: Iterable[int], per: int) -> None:
        self._alive("setting mesh connectivity")
        mesh = self._require_mesh_modify(mesh_name)
        if not self.requires_mesh_connectivity_for(mesh_name):
            return
        ids = [int(v) for v in vertex_ids]
        if len(ids) % per:
            raise PreciceError(
                f'Cannot interpret passed vertex IDs attempting to set connectivity of mesh "'
                f'{mesh_name}". You passed {len(ids)} vertex indices, but we expected a '
                f"multiple of {per}."
            )
        for vid in ids:
            if not 0 <= vid < mesh.n:
                raise PreciceError(
                    f'The given VertexID "{vid}" is invalid. Check that it originated from a '
                    "call to setMeshVertex() or setMeshVertices()."
                )

    def set_mesh_edge(self, mesh_name: str, first_vertex_id: int, second_vertex_id: int) -> None:
        self._connectivity(_convert(mesh_name), [first_vertex_id, second_vertex_id], 2)

    def set_mesh_edges(self, mesh_name: str, vertices: Any) -> None:
        _check_array_like(vertices, "vertices", "set_mesh_edges")
        arr = np.asarray(vertices)
        if len(arr) > 0:
            _, n = arr.shape
            assert n == 2, (
                f"Provided vertices are not of a [N x 2] format, but instead of a [N x {n}]"
            )
        self._connectivity(_convert(mesh_name), arr.reshape(-1), 2)

    def set_mesh_triangle(
        self, mesh_name: str, first_vertex_id: int, second_vertex_id: int, third_vertex_id: int
    ) -> None:
        ids = [first_vertex_id, second_vertex_id, third_vertex_id]
        self._connectivity(_convert(mesh_name), ids, 3)

    def set_mesh_triangles(self, mesh_name: str, vertices: Any) -> None:
        _check_array_like(vertices, "vertices", "set_mesh_triangles")
        arr = np.asarray(vertices)
        self._connectivity(_convert(mesh_name), arr.reshape(-1), 3)

    def set_mesh_quad(
        self,
        mesh_name: str,
        first_vertex_id: int,
        second_vertex_id: int,
        third_vertex_id: int,
        fourth_vertex_id: int,
    ) -> None:
        ids = [first_vertex_id, second_vertex_id, third_vertex_id, fourth_vertex_id]
        self._connectivity(_convert(mesh_name), ids, 4)

    def set_mesh_quads(self, mesh_name: str, vertices: Any) -> None:
        _check_array_like(vertices, "vertices", "set_mesh_quads")
        arr = np.asarray(vertices)
        if len(arr) > 0:
            _, n = arr.shape
            assert n == 4, (
                f"Provided vertices are not of a [N x 4] format, but instead of a [N x {n}]"
            )
        self._connectivity(_convert(mesh_name), arr.reshape(-1), 4)

    def set_mesh_tetrahedron(
        self,
        mesh_name: str,
        first_vertex_id: int,
        second_vertex_id: int,
        third_vertex_id: int,
        fourth_vertex_id: int,
    ) -> None:
        ids = [first_vertex_id, second_vertex_id, third_vertex_id, fourth_vertex_id]
        self._connectivity(_convert(mesh_name), ids, 4)

    def set_mesh_tetrahedra(self, mesh_name: str, vertices: Any) -> None:
        _check_array_like(vertices, "vertices", "set_mesh_tetrahedra")
        arr = np.asarray(vertices)
        if len(arr) > 0:
            _, n = arr.shape
            assert n == 4, (
                f"Provided vertices are not of a [N x 4] format, but instead of a [N x {n}]"
            )
        self._connectivity(_convert(mesh_name), arr.reshape(-1), 4)

    def reset_mesh(self, mesh_name: str) -> None:
        self._require_experimental("resetMesh")
        if not self._allow_remeshing:
            raise PreciceError(
                "Cannot reset meshes. This feature needs to be enabled using "
                '<precice-configuration experimental="1" allow-remeshing="1">.'
            )
        raise PreciceError("gymprecice's fake_precice does not model remeshing (reset_mesh).")

    # ----------------------------------------------------------------- data access

    def write_data(self, mesh_name: str, data_name: str, vertex_ids: Any, values: Any) -> None:
        _check_array_like(vertex_ids, "vertex_ids", "write_data")
        _check_array_like(values, "values", "write_data")
        self._alive("writeData(...)")
        mesh_n, data_n = _convert(mesh_name), _convert(data_name)
        if not isinstance(values, np.ndarray):
            values = np.asarray(values)
        if len(values) == 0:
            size = 0
        elif self.get_data_dimensions(mesh_n, data_n) == 1:
            size = values.flatten().shape[0]
        else:
            assert len(values.shape) == 2, (
                "Vector valued data has to be provided as a numpy array of shape [N x D] where "
                "N = number of vertices and D = number of dimensions."
            )
            size, dimensions = values.shape
            expected = self.get_data_dimensions(mesh_n, data_n)
            assert dimensions == expected, (
                "Dimensions of vector data in write_data do not match with dimensions in problem "
                f"definition. Provided dimensions: {dimensions}, expected dimensions: {expected}"
            )
        assert len(vertex_ids) == size, (
            "Vertex IDs are of incorrect length in write_data. Check length of vertex ids input. "
            f"Provided size: {vertex_ids.size}, expected size: {size}"
        )
        if self._state == "finalized":
            raise PreciceError("writeData(...) cannot be called after finalize().")
        if not (self._state == "constructed" or self._check_ongoing()):
            raise PreciceError(
                "Calling writeData(...) is forbidden if coupling is not ongoing, because the data "
                "you are trying to write will not be used anymore. You can fix this by always "
                "calling writeData(...) before the advance(...) call in your simulation loop or "
                "by using Participant::isCouplingOngoing() to implement a safeguard."
            )
        mesh = self._require_data_access(mesh_n, data_n, write=True)
        ids = _ids(vertex_ids)
        if size == 0:
            return
        dim = self._data_dims(data_n, mesh_n)
        flat = np.asarray(values, dtype=np.float64).reshape(-1)
        if flat.size != size * dim:
            raise PreciceError(
                f'Input sizes are inconsistent attempting to write {dim}D data "{data_n}" to '
                f'mesh "{mesh_n}". You passed {len(ids)} vertex indices and {flat.size} data '
                f"components, but we expected {size * dim} data components ({dim} x {len(ids)})."
            )
        invalid = np.nonzero((ids < 0) | (ids >= mesh.n))[0]
        if len(invalid):
            raise PreciceError(
                f'Cannot write data "{data_n}" to mesh "{mesh_n}" due to invalid Vertex ID at '
                f"vertices[{int(invalid[0])}]. Please make sure you only use the results from "
                "calls to setMeshVertex/Vertices()."
            )
        buf = self._buffer(data_n, mesh_n)
        buf[ids] = flat.reshape(-1, dim)

    def read_data(
        self, mesh_name: str, data_name: str, vertex_ids: Any, relative_read_time: float
    ) -> np.ndarray:
        _check_array_like(vertex_ids, "vertex_ids", "read_data")
        self._alive("readData(...)")
        mesh_n, data_n = _convert(mesh_name), _convert(data_name)
        dims = self.get_data_dimensions(mesh_n, data_n)
        size = len(vertex_ids)
        rel = float(relative_read_time)
        if self._state == "constructed":
            raise PreciceError("readData(...) cannot be called before initialize().")
        if self._state == "finalized":
            raise PreciceError("readData(...) cannot be called after finalize().")
        scheme = self._scheme
        if not (rel - scheme.next_max() <= _NUMERICAL_ZERO):
            raise PreciceError("readData(...) cannot sample data outside of current time window.")
        if rel < 0:
            raise PreciceError("readData(...) cannot sample data before the current time.")
        if not (scheme.is_ongoing() or _equals(rel, 0.0)):
            raise PreciceError(
                f"Calling readData(...) with relativeReadTime = {rel!r} is forbidden if coupling "
                "is not ongoing. If coupling finished, only data for relativeReadTime = 0 is "
                "available. Please always use precice.getMaxTimeStepSize() to obtain the maximum "
                "allowed relativeReadTime."
            )
        mesh = self._require_data_access(mesh_n, data_n, write=False)
        if size == 0:
            return np.zeros(0)
        assert self._coupling is not None
        wave = self._coupling.store.wave((data_n, mesh_n))
        if not len(wave):
            raise PreciceError(
                f'Data "{data_n}" cannot be read from mesh "{mesh_n}" as it contains no samples. '
                "This is typically a configuration issue of the data flow. Check if the data is "
                f'correctly exchanged to this participant "{self._name}" and mapped to mesh '
                f'"{mesh_n}".'
            )
        ids = _ids(vertex_ids)
        invalid = np.nonzero((ids < 0) | (ids >= mesh.n))[0]
        if len(invalid):
            raise PreciceError(
                f'Cannot read data "{data_n}" from mesh "{mesh_n}" due to invalid Vertex ID at '
                f"vertices[{int(invalid[0])}]. Please make sure you only use the results from "
                "calls to setMeshVertex/Vertices()."
            )
        values = wave.sample(scheme.get_time() + rel, self._degrees[data_n])[ids]
        out = np.array(values, dtype=np.float64)
        return out.reshape(size) if dims == 1 else out.reshape(size, dims)

    def write_and_map_data(
        self, mesh_name: str, data_name: str, coordinates: Any, values: Any
    ) -> None:
        self._require_experimental("writeAndMapData")
        raise PreciceError("gymprecice's fake_precice does not model just-in-time mappings.")

    def map_and_read_data(
        self, mesh_name: str, data_name: str, coordinates: Any, relative_read_time: float
    ) -> np.ndarray:
        self._require_experimental("mapAndReadData")
        raise PreciceError("gymprecice's fake_precice does not model just-in-time mappings.")

    def write_gradient_data(
        self, mesh_name: str, data_name: str, vertex_ids: Any, gradients: Any
    ) -> None:
        self._require_experimental("writeGradientData")
        if self._state == "finalized":
            raise PreciceError("writeGradientData(...) cannot be called after finalize().")
        self._require_data_access(_convert(mesh_name), _convert(data_name), write=True)
        # No data of the double carries gradients, so (like preCICE then) this is a no-op.

    def requires_gradient_data_for(self, mesh_name: str, data_name: str) -> bool:
        self._alive("requiresGradientDataFor()")
        self._validate_data(_convert(mesh_name), _convert(data_name))
        return False

    def set_mesh_access_region(self, mesh_name: str, bounding_box: Any) -> None:
        _check_array_like(bounding_box, "bounding_box", "set_mesh_access_region")
        self._alive("setMeshAccessRegion()")
        name = _convert(mesh_name)
        box = np.asarray(bounding_box, dtype=np.float64).reshape(-1)
        assert len(box) > 0, "Bounding box cannot be empty."
        assert len(box) == self.get_mesh_dimensions(name) * 2, (
            "Dimensions of bounding box in set_mesh_access_region does not match with dimensions "
            "in problem definition."
        )
        mesh = self._require_direct_access(
            name, "setMeshAccessRegion", "set an access region", preposition="on mesh"
        )
        if self._state == "finalized":
            raise PreciceError("setMeshAccessRegion() cannot be called after finalize().")
        if self._state == "initialized":
            raise PreciceError("setMeshAccessRegion() needs to be called before initialize().")
        if mesh.region is not None:
            raise PreciceError(
                f'A mesh access region was already defined for mesh "{name}". '
                "setMeshAccessRegion may only be called once per mesh."
            )
        if np.any(box[0::2] > box[1::2]):
            raise PreciceError(
                "Your bounding box is ill defined, i.e. it has a negative volume. The required "
                "format is [x_min, x_max...]"
            )
        mesh.region = box

    def get_mesh_vertex_ids_and_coordinates(self, mesh_name: str) -> tuple[np.ndarray, np.ndarray]:
        self._alive("getMeshVertexIDsAndCoordinates()")
        name = _convert(mesh_name)
        size = self.get_mesh_vertex_size(name)
        dims = self.get_mesh_dimensions(name)
        mesh = self._require_direct_access(
            name, "getMeshVertexIDsAndCoordinates", "get mesh vertex IDs and coordinates"
        )
        inside = mesh.in_region()
        assert len(inside) == size
        ids = inside.astype(np.int32)
        coords = np.array(mesh.coordinates[inside], dtype=np.float64).reshape(size, dims)
        return ids, coords

    # ----------------------------------------------------------------- profiling

    def start_profiling_section(self, event_name: str) -> None:
        name = _convert(event_name)
        if "/" in name:
            _fatal(
                "abort", f'The provided section name "{name}" may not contain a forward-slash "/"'
            )
        self._user_events.append(name)

    def stop_last_profiling_section(self) -> None:
        if not self._user_events:
            _fatal("abort", "There is no user-started event to stop.")
        self._user_events.pop()

    # ----------------------------------------------------------------- internals

    def _buffer(self, data: str, mesh_name: str) -> np.ndarray:
        key = (data, mesh_name)
        buf = self._buffers.get(key)
        resized = self._resized(buf, data, mesh_name)
        if resized is not buf:
            self._buffers[key] = resized
        return resized

    def _resized(self, buf: np.ndarray | None, data: str, mesh_name: str) -> np.ndarray:
        n = self._meshes[mesh_name].n
        dim = self._data_dims(data, mesh_name)
        if buf is not None and buf.shape == (n, dim):
            return buf
        new = np.zeros((n, dim))
        if buf is not None:
            k = min(len(buf), n)
            new[:k] = buf[:k]
        return new

    def _reset_written(self) -> None:
        for buf in self._buffers.values():
            buf.fill(0.0)

    def _mapped(self, mesh_name: str) -> bool:
        return any(mesh_name in (m.from_mesh, m.to_mesh) for m in self._spec.mappings)

    def _build_mappings(self, coupling: _Coupling) -> None:
        self._read_maps: list[tuple[_Mapping, str]] = []
        self._write_maps: list[tuple[_Mapping, str]] = []
        for spec in self._spec.mappings:
            source = self._meshes.get(spec.from_mesh)
            target = self._meshes.get(spec.to_mesh)
            if source is None or target is None:
                missing = spec.from_mesh if source is None else spec.to_mesh
                raise PreciceError(
                    f'Participant "{self._name}" defines a mapping with mesh "{missing}", which it '
                    "neither provides nor receives."
                )
            if spec.method != "nearest-neighbor":
                self._log(
                    f'fake_precice runs mapping "{spec.method}" from "{spec.from_mesh}" to '
                    f'"{spec.to_mesh}" as nearest-neighbor'
                )
            mapping = _Mapping(spec, source.coordinates, target.coordinates)
            shared = [
                d
                for d in self._cfg.meshes[spec.from_mesh].data
                if d in self._cfg.meshes[spec.to_mesh].data
            ]
            if spec.direction == "read":
                for data in shared:
                    if (data, spec.to_mesh) in self._reads:
                        self._read_maps.append((mapping, data))
            else:
                for data in shared:
                    if (data, spec.from_mesh) in self._writes:
                        self._write_maps.append((mapping, data))

    def _map_written(self, after: float | None) -> None:
        assert self._coupling is not None
        store = self._coupling.store
        for mapping, data in self._write_maps:
            source = store.wave((data, mapping.spec.from_mesh))
            target = store.wave((data, mapping.spec.to_mesh))
            if after is not None:
                target.trim_after(after)
            for t, v in zip(source.times, source.values):
                if after is None or _greater(t, after):
                    target.set(t, mapping.apply(v))

    def _map_read(self) -> None:
        assert self._coupling is not None
        store = self._coupling.store
        for mapping, data in self._read_maps:
            source = store.wave((data, mapping.spec.from_mesh))
            target = _Waveform()
            for t, v in zip(source.times, source.values):
                target.set(t, mapping.apply(v))
            store.waves[(data, mapping.spec.to_mesh)] = target

    # -- connection set-up (initialize)

    def _links(self) -> list[tuple[str, str, str]]:
        """(acceptor, connector, exchange directory) of every m2n this participant is part of."""
        links = []
        for m2n in self._cfg.m2n:
            if self._name in (m2n.acceptor, m2n.connector):
                links.append((m2n.acceptor, m2n.connector, m2n.exchange_directory or "."))
        return sorted(links)

    def _connect(self, coupling: _Coupling) -> None:
        links = self._links()
        partners = {a if c == self._name else c for a, c, _ in links}
        needed = set()
        for scheme in self._scheme.schemes:
            needed.update(scheme.partners)
        needed.update(self._spec.received_meshes.values())
        for other in self._cfg.participants.values():
            if any(src == self._name for src in other.received_meshes.values()):
                needed.add(other.name)
        needed.discard(self._name)
        for partner in sorted(needed - partners):
            coupling.channel(partner)  # raises with the m2n advice
        listeners: list[tuple[str, str, Path, socket.socket, Path]] = []
        for acceptor, connector, directory in links:
            if acceptor != self._name:
                continue
            link_dir = Path(directory) / "precice-run" / f"{acceptor}-{connector}"
            address = link_dir / _ADDRESS_FILE
            if address.exists():
                raise PreciceError(
                    "Unable to establish connection as a connection file already exists at "
                    f'"{address}". This is likely a leftover of a previous crash or stop during '
                    'communication build-up. Please remove the "precice-run" directory and '
                    "restart the simulation."
                )
            sock_dir = _short_socket_dir()
            sock_path = sock_dir / "s"
            server = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
            server.bind(str(sock_path))
            server.listen(1)
            link_dir.mkdir(parents=True, exist_ok=True)
            tmp = link_dir / (_ADDRESS_FILE + "~")
            tmp.write_text(f"{sock_path}\nAcceptor: {acceptor}, Requester: {connector}\n")
            os.replace(tmp, address)
            listeners.append((connector, acceptor, address, server, sock_dir))
        hello = {"participant": self._name, "version": PRECICE_VERSION, "hash": self._config_hash}
        pending: list[_Channel] = []
        for acceptor, connector, directory in links:
            if connector != self._name:
                continue
            link_dir = Path(directory) / "precice-run" / f"{acceptor}-{connector}"
            sock = self._request(link_dir, acceptor)
            ch = _Channel(sock, self._name, acceptor)
            ch.send("hello", hello)
            pending.append(ch)
        for connector, _acceptor, address, server, sock_dir in listeners:
            conn, _ = server.accept()
            server.close()
            with contextlib.suppress(OSError):
                address.unlink()
            with contextlib.suppress(OSError):
                (sock_dir / "s").unlink()
                sock_dir.rmdir()
            ch = _Channel(conn, self._name, connector)
            remote, _ = ch.recv("hello")
            self._check_hello(remote, connector)
            ch.send("hello", hello)
            coupling.channels[connector] = ch
        for ch in pending:
            remote, _ = ch.recv("hello")
            self._check_hello(remote, ch.remote)
            coupling.channels[ch.remote] = ch

    def _request(self, link_dir: Path, acceptor: str) -> socket.socket:
        """Wait (forever, like preCICE) for the acceptor's address, then connect."""
        address = link_dir / _ADDRESS_FILE
        while True:
            try:
                text = address.read_text()
            except OSError:
                if link_dir.is_dir() and any(
                    p.name != _ADDRESS_FILE and not p.name.endswith("~") for p in link_dir.iterdir()
                ):
                    raise PreciceError(
                        f'Participant "{acceptor}" publishes its address in "{link_dir}" the way '
                        "real preCICE does, but this participant runs gymprecice's fake_precice. "
                        "Mixing preCICE versions can lead to undefined behavior and is, thus, "
                        "forbidden: run every participant with the same library."
                    ) from None
                time.sleep(_POLL_SECONDS)
                continue
            path = text.splitlines()[0].strip() if text else ""
            sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
            try:
                sock.connect(path)
            except OSError:
                sock.close()
                time.sleep(_POLL_SECONDS)
                continue
            return sock

    def _check_hello(self, remote: dict[str, str], expected: str) -> None:
        if remote.get("participant") != expected:
            raise PreciceError(
                f'Expected to be connected to participant "{expected}" but participant '
                f'"{remote.get("participant")}" answered. Check the m2n tags of the configuration.'
            )
        if remote.get("version") != PRECICE_VERSION:
            raise PreciceError(
                f"This participant {self._name} uses preCICE version {PRECICE_VERSION} but the "
                f"requester participant {expected} uses preCICE version {remote.get('version')}. "
                "Mixing preCICE versions can lead to undefined behavior and is, thus, forbidden."
            )
        if remote.get("hash") != self._config_hash:
            raise PreciceError(
                f"This participant {self._name} uses a different configuration file than the "
                f"remote participant {expected}. Hashes differ {self._config_hash} != "
                f"{remote.get('hash')}."
            )

    def _exchange_meshes(self, coupling: _Coupling) -> None:
        """Send provided meshes to their receivers; one link at a time, in a global order."""
        for acceptor, connector, _ in self._links():
            partner = connector if acceptor == self._name else acceptor
            ch = coupling.channels[partner]
            outgoing = sorted(
                m
                for m, src in self._cfg.participants[partner].received_meshes.items()
                if src == self._name
            )
            incoming = sorted(m for m, src in self._spec.received_meshes.items() if src == partner)
            for name in outgoing:
                if name not in self._spec.provided_meshes:
                    raise PreciceError(
                        f'Participant "{partner}" receives mesh "{name}" from "{self._name}", '
                        f'but "{self._name}" does not provide it (<provide-mesh name="{name}" />).'
                    )
            if acceptor == self._name:
                self._send_meshes(ch, outgoing)
                self._receive_meshes(ch, incoming)
            else:
                self._receive_meshes(ch, incoming)
                self._send_meshes(ch, outgoing)

    def _send_meshes(self, ch: _Channel, names: list[str]) -> None:
        ch.send("meshes", names, [self._meshes[n].coordinates for n in names])

    def _receive_meshes(self, ch: _Channel, names: list[str]) -> None:
        sent, arrays = ch.recv("meshes")
        got = dict(zip(sent, arrays))
        for name in names:
            if name not in got:
                raise PreciceError(
                    f'Participant "{ch.remote}" did not send mesh "{name}"; check that it '
                    f'provides it (<provide-mesh name="{name}" />).'
                )
            mesh = self._meshes[name]
            mesh.chunks = [np.array(got[name], dtype=np.float64).reshape(-1, mesh.dims)]
            mesh.coords = None


def _logs_errors(method: Any) -> Any:
    """preCICE logs every error it throws; do the same once per error, then re-raise."""

    @functools.wraps(method)
    def wrapper(self: Participant, *args: Any, **kwargs: Any) -> Any:
        try:
            return method(self, *args, **kwargs)
        except PreciceError as exc:
            if not getattr(exc, "logged", False):
                exc.logged = True  # type: ignore[attr-defined]
                self._log(f"ERROR: {exc}")
            raise

    return wrapper


for _name, _method in list(vars(Participant).items()):
    if callable(_method) and not _name.startswith("_"):
        setattr(Participant, _name, _logs_errors(_method))
del _name, _method
