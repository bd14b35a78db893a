"""The function objects a case's ``system/controlDict`` lists, ``#include`` files resolved.

Cases keep their function objects in files of their own (``#include "probes"`` inside
``functions``), which foamlib leaves as ``#include`` entries; :func:`function_objects`
reads those files too, so that callers see every entry by name. Used by ``gymprecice
sketch`` to find the probes an environment observes (:func:`probe_sets`).

A ``probeLocations`` list is read with numpy, not handed to foamlib: foamlib's parser takes
seconds per hundred points (13 s for the cylinders' 151 probes on a busy 2-core machine).
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gymprecice.plugin import CaseError
from gymprecice_openfoam import control, foamio

__all__ = ["ProbeSet", "function_objects", "probe_sets"]

_INCLUDES = ("#include", "#includeIfPresent", "#includeEtc")


#: a ``probeLocations`` list of points: ``probeLocations ( (x y z) ... );``
_LOCATIONS = re.compile(rb"probeLocations\s*\(((?:\s*\([^()]*\))*)\s*\)\s*;")
_PLACEHOLDER = "gymprecice_probe_locations_"


def _load(path: Path) -> Any:
    """The parsed file, each ``probeLocations`` list read by numpy (see the module)."""
    found, data = foamio.read_bytes(path)
    lists: list[np.ndarray] = []

    def keep(match: re.Match[bytes]) -> bytes:
        numbers = match.group(1).replace(b"(", b" ").replace(b")", b" ").decode()
        lists.append(np.array(numbers.split(), dtype=float).reshape(-1, 3))
        return f"probeLocations {_PLACEHOLDER}{len(lists) - 1};".encode()

    parsed = foamio.loads(found, _LOCATIONS.sub(keep, data))
    if lists:
        _restore(parsed, lists)
    return parsed


def _restore(value: Any, lists: list[np.ndarray]) -> None:
    """Put the numpy-read lists back where their placeholders are."""
    if not hasattr(value, "items"):
        return
    for key, entry in list(value.items()):
        if isinstance(entry, str) and entry.startswith(_PLACEHOLDER):
            value[key] = lists[int(entry[len(_PLACEHOLDER) :])]
        else:
            _restore(entry, lists)


def _entries(mapping: Any, directory: Path, depth: int = 0) -> Iterator[tuple[str, Any]]:
    """``(name, entry)`` of a ``functions`` dictionary, following ``#include`` files."""
    items = mapping.items() if hasattr(mapping, "items") else ()
    for key, value in items:
        if str(key) in _INCLUDES:
            if depth > 8:
                raise CaseError(f"{directory}: #include nested more than 8 deep in functions")
            path = directory / str(value).strip('"')
            if not path.is_file():
                if str(key) == "#include":
                    raise CaseError(
                        f"{path}: included by controlDict's functions but missing; add the "
                        "file or remove the #include"
                    )
                continue
            yield from _entries(_load(path), path.parent, depth + 1)
        elif str(key) != "FoamFile":
            yield str(key), value


def function_objects(case_dir: str | os.PathLike[str]) -> dict[str, dict[str, Any]]:
    """Every function object of the case, by name (only dictionary entries)."""
    path = control.control_dict_path(case_dir)
    if not path.is_file():
        control.read_control_dict(case_dir)  # its error names the missing file and the fix
    functions = _load(path).get("functions")
    if isinstance(functions, list):  # the old list form: functions ( name { ... } ... );
        functions = dict(enumerate(functions))
    return {
        name: entry
        for name, entry in _entries(functions or {}, path.parent)
        if isinstance(entry, dict)
    }


@dataclass(frozen=True, eq=False)
class ProbeSet:
    """One ``probes`` function object: its name, the fields it samples and where."""

    name: str
    fields: tuple[str, ...]
    locations: np.ndarray

    @property
    def label(self) -> str:
        fields = f" ({', '.join(self.fields)})" if self.fields else ""
        return f"OpenFOAM {self.name}{fields}: {len(self.locations)}"


def probe_sets(case_dir: str | os.PathLike[str]) -> list[ProbeSet]:
    """The case's ``probes`` function objects with their ``probeLocations``."""
    found = []
    for name, entry in function_objects(case_dir).items():
        if str(entry.get("type", "")) != "probes" or "probeLocations" not in entry:
            continue
        locations = np.asarray(entry["probeLocations"], dtype=float).reshape(-1, 3)
        fields = entry.get("fields", ())
        fields = (fields,) if isinstance(fields, str) else tuple(str(f) for f in fields)
        found.append(ProbeSet(name, fields, locations))
    return found
