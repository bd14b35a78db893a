"""``system/controlDict`` of a run directory: read it, find the preCICE adapter, edit times.

The OpenFOAM-preCICE adapter is a function object (``type preciceAdapterFunctionObject``,
library ``libpreciceAdapterFunctionObject.so``) listed under ``functions``. Whether it is
there decides whether a run is coupled: an uncoupled pre-run needs it removed, and a
coupled episode without it would run on its own while the controller waits forever.
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from gymprecice.plugin import CaseError
from gymprecice_openfoam import foamio

ADAPTER_TYPE = "preciceAdapterFunctionObject"
ADAPTER_LIB = "libpreciceAdapterFunctionObject.so"

#: The entry users paste into ``functions`` to couple a case (quoted in error messages).
ADAPTER_SNIPPET = (
    "functions { preCICE_Adapter { type preciceAdapterFunctionObject; "
    'libs ("libpreciceAdapterFunctionObject.so"); } }'
)

_INCLUDE = re.compile(r'^\s*#include(?:Etc|IfPresent)?\s+"([^"]+)"', re.M)
_COMMENTS = re.compile(r"//[^\n]*|/\*.*?\*/", re.S)


def control_dict_path(case_dir: str | os.PathLike[str]) -> Path:
    return Path(case_dir) / "system" / "controlDict"


def read_control_dict(case_dir: str | os.PathLike[str]) -> dict[str, Any]:
    """The parsed controlDict, or :class:`CaseError` when the case has none."""
    path = control_dict_path(case_dir)
    if not path.is_file():
        raise CaseError(
            f"{path}: missing; every OpenFOAM case needs system/controlDict (application, "
            "times, function objects). Is the solver path pointing at the case directory?"
        )
    parsed = foamio.load(path)
    if not isinstance(parsed, dict):
        raise CaseError(f"{path}: not a dictionary")
    return parsed


def application(case_dir: str | os.PathLike[str], override: str | None = None) -> str:
    """The solver to run: ``override`` (option ``application``) or controlDict's entry."""
    if override:
        return str(override)
    control = read_control_dict(case_dir)
    app = control.get("application")
    if not app:
        raise CaseError(
            f"{control_dict_path(case_dir)}: no 'application' entry; add e.g. "
            "'application pimpleFoam;' or set the solver option \"application\""
        )
    return str(app)


def _is_adapter(entry: object) -> bool:
    if not isinstance(entry, dict):
        return False
    if str(entry.get("type", "")) == ADAPTER_TYPE:
        return True
    libs = entry.get("libs", entry.get("functionObjectLibs", ()))
    if isinstance(libs, str):
        libs = [libs]
    return any(ADAPTER_LIB in str(lib) or "preciceAdapter" in str(lib) for lib in libs or ())


def adapter_entries(case_dir: str | os.PathLike[str]) -> list[str]:
    """Names of the ``functions`` entries that load the preCICE adapter."""
    functions = read_control_dict(case_dir).get("functions")
    if isinstance(functions, dict):
        return [name for name, entry in functions.items() if _is_adapter(entry)]
    if isinstance(functions, list):  # old list syntax: functions ( name { ... } ... );
        return [str(i) for i, entry in enumerate(functions) if _is_adapter(entry)]
    return []


def mentions_adapter(case_dir: str | os.PathLike[str]) -> bool:
    """Whether controlDict (or a file it ``#include``s) loads the adapter.

    Catches set-ups the dictionary view cannot see, such as the adapter's entry in an
    included file.
    """
    path = control_dict_path(case_dir)
    seen: set[Path] = set()
    todo = [path]
    while todo:
        current = todo.pop()
        if current in seen or not current.is_file():
            continue
        seen.add(current)
        text = _COMMENTS.sub(" ", current.read_text(errors="replace"))
        if ADAPTER_TYPE in text or ADAPTER_LIB in text:
            return True
        for name in _INCLUDE.findall(text):
            included = Path(name)
            todo.append(included if included.is_absolute() else current.parent / included)
    return False


def has_adapter(case_dir: str | os.PathLike[str]) -> bool:
    """True when the case is set up to couple through preCICE."""
    return bool(adapter_entries(case_dir)) or mentions_adapter(case_dir)


def _number(value: float) -> float:
    """A float that prints short (0.235, not 0.23500000000000001)."""
    return float(f"{value:.12g}")


@contextmanager
def uncoupled_control_dict(
    case_dir: str | os.PathLike[str], *, end_time: float, start_time: float, adjustable: bool
) -> Iterator[bool]:
    """Temporarily rewrite controlDict for an uncoupled pre-run segment.

    Removes the preCICE adapter's function object, starts from the latest time, stops at
    ``end_time`` and writes exactly there. The original bytes are put back on exit, even
    after a failure. Yields False when the adapter is loaded in a way this edit cannot
    remove (e.g. from an included file): the caller then disables function objects.
    """
    path = control_dict_path(case_dir)
    original = path.read_bytes()
    try:
        removable = adapter_entries(case_dir)
        from foamlib import FoamFile  # imported when used: see foamio.loads

        with FoamFile(path) as control:
            for name in removable:
                del control["functions", name]
            control["startFrom"] = "latestTime"
            control["stopAt"] = "endTime"
            control["endTime"] = _number(end_time)
            control["writeControl"] = "adjustableRunTime" if adjustable else "runTime"
            control["writeInterval"] = _number(max(end_time - start_time, 1e-300))
            control["purgeWrite"] = 0
        yield not mentions_adapter(case_dir)
    finally:
        path.write_bytes(original)


#: the entries :func:`uncoupled_control_dict` sets for a pre-run segment, whatever the
#: case had (with ``startFrom latestTime``, ``startTime`` is not read)
PRERUN_OVERRIDES = (
    "startFrom",
    "startTime",
    "stopAt",
    "endTime",
    "writeControl",
    "writeInterval",
    "purgeWrite",
)
_OVERRIDDEN = re.compile(
    rb"^(" + b"|".join(k.encode() for k in PRERUN_OVERRIDES) + rb")[ \t]+[^;\n]*;", re.M
)


def as_a_prerun_reads_it(control_dict: bytes) -> bytes:
    """A controlDict's bytes without the values a pre-run overrides.

    An episode's length changes ``endTime`` and ``writeInterval`` in the case (and a
    start changes ``startTime``), not what a pre-run computes: the pre-run cache hashes
    this instead of the file, so a training's envs, its validation env (longer episodes)
    and an evaluation share one pre-run. Only top-level entries written one a line are
    recognised; any other form stays in the hash (a distinct entry, never a wrong one).
    """
    return _OVERRIDDEN.sub(rb"\1 <pre-run>;", control_dict)


def set_start(
    case_dir: str | os.PathLike[str], start_name: str, *, end_time: float | None = None
) -> bool:
    """Make the case start at time directory ``start_name``; True when the file changed.

    Leaves controlDict alone when it already resolves to that time, so a reset that
    keeps the same start does not touch the file.
    """
    control = read_control_dict(case_dir)
    start = float(start_name)
    changes: dict[str, Any] = {}
    if str(control.get("startFrom", "startTime")) != "startTime":
        changes["startFrom"] = "startTime"
    current = control.get("startTime")
    try:
        same = current is not None and abs(float(current) - start) <= 1e-12 * max(1.0, start)
    except (TypeError, ValueError):
        same = False
    if not same:
        changes["startTime"] = _number(start)
    if end_time is not None:
        try:
            old_end = float(control.get("endTime", 0.0))
        except (TypeError, ValueError):
            old_end = 0.0
        if abs(old_end - end_time) > 1e-12 * max(1.0, end_time):
            changes["endTime"] = _number(end_time)
    if not changes:
        return False
    from foamlib import FoamFile  # imported when used: see foamio.loads

    with FoamFile(control_dict_path(case_dir)) as f:
        for key, value in changes.items():
            f[key] = value
    return True


def float_entry(case_dir: str | os.PathLike[str], key: str, default: float) -> float:
    value = read_control_dict(case_dir).get(key, default)
    try:
        return float(value)
    except (TypeError, ValueError):
        return default


def _disabled(entry: object) -> bool:
    """OpenFOAM reads ``enabled`` as a Switch (false/off/no/none/0) and skips the object."""
    if not isinstance(entry, dict) or "enabled" not in entry:
        return False
    value = entry["enabled"]
    if isinstance(value, str):
        return value.strip().lower() in ("false", "off", "no", "n", "f", "none")
    return not bool(value)


def disabled_adapter_entries(case_dir: str | os.PathLike[str]) -> list[str]:
    """Names of adapter entries in ``functions`` that say ``enabled false;``."""
    functions = read_control_dict(case_dir).get("functions")
    if isinstance(functions, dict):
        items = list(functions.items())
    elif isinstance(functions, list):
        items = [(str(i), entry) for i, entry in enumerate(functions)]
    else:
        items = []
    return [name for name, entry in items if _is_adapter(entry) and _disabled(entry)]


def adapter_libraries(case_dir: str | os.PathLike[str]) -> list[str]:
    """The library names the adapter entries load, as written in controlDict."""
    functions = read_control_dict(case_dir).get("functions")
    entries = functions.values() if isinstance(functions, dict) else functions or ()
    names: list[str] = []
    for entry in entries:
        if not _is_adapter(entry):
            continue
        libs = entry.get("libs", entry.get("functionObjectLibs", ()))
        for lib in [libs] if isinstance(libs, str) else libs or ():
            name = str(lib).strip('"')
            if name not in names:
                names.append(name)
    return names
