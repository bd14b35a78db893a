"""Starts from FSI3's swinging state: a library of saved fluid and solid states.

Uncontrolled, FSI3 takes about six simulated seconds from rest to its periodic swing
(the inflow's ramp, then the shedding's growth; ``docs/validation.md``). An episode that
had to pay for those seconds every time would spend most of its cost before the first
action mattered, so the control env starts from states of the periodic swing instead,
as the cylinders start from snapshots of their shedding.

A start is two states saved at the same simulated time by one uncontrolled coupled run
(:mod:`.build_starts`): the fluid's time directory (OpenFOAM: the flow, the deformed
mesh and its motion) and the FEniCS bar's state (displacement, velocity and
acceleration: ``Bar.save``). The deal.II program cannot restart, so starts need
``solid="fenics"``. A library is a folder::

    <library>/starts.json          the case the states belong to, the times, the split
    <library>/fluid/<time>/...     OpenFOAM's time directory of each start
    <library>/solid/state-<time>.npz
    <library>/uncontrolled.npz     the run's tip displacement, drag and lift from the
                                   first start on (what an uncontrolled episode repeats)

The split follows the cylinders' snapshots (:func:`gymprecice_openfoam.case.split_snapshots`):
every fourth start is held out (``reset(options={"split": "eval", "start": k})``), a
quarter of the rest validates (``"validation"``), training draws from the others.

The registered env (``gymprecice/TurekHronFSI3-v0``) and the build look for the library
in one place per user unless told another, :func:`default_starts`:
``$XDG_DATA_HOME/gymprecice/turek-hron-fsi3/starts`` (``~/.local/share/...`` without
``XDG_DATA_HOME``), beside what ``gymprecice install`` builds.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from pathlib import Path

__all__ = [
    "BUILD_COMMAND",
    "BUILD_COST",
    "INDEX",
    "UNCONTROLLED",
    "StartLibrary",
    "default_starts",
    "load",
    "split",
    "start_times",
]

#: the library's description, beside its states
INDEX = "starts.json"
#: the uncontrolled run's series from the first start on (``validate``'s signals), which
#: an episode from a start without control should repeat
UNCONTROLLED = "uncontrolled.npz"
#: the command that builds a library (``--out DIR`` puts it elsewhere than the default)
BUILD_COMMAND = "python -m gymprecice_tutorials.turek_hron.build_starts"
#: what building the full library costs (the build's defaults: 6.22 s of the coupled run;
#: 71 min measured on 2 cores, docs/validation.md)
BUILD_COST = "about 70 min on 2 cores"


def default_starts() -> Path:
    """Where the registered env looks for its library and the build puts it unless told
    another: ``$XDG_DATA_HOME/gymprecice/turek-hron-fsi3/starts`` (``XDG_DATA_HOME``
    defaults to ``~/.local/share``, as for :func:`gymprecice.tools.stack.stack_prefix`)."""
    data = os.environ.get("XDG_DATA_HOME") or str(Path.home() / ".local" / "share")
    return Path(data).expanduser() / "gymprecice" / "turek-hron-fsi3" / "starts"


@dataclass(frozen=True)
class StartLibrary:
    """A built library of starts (see the module): where it is and what it holds."""

    path: Path
    resolution: str
    time_step: float
    degree: int
    times: tuple[str, ...]
    split: dict[str, list[str]]

    def fluid_dir(self, name: str) -> Path:
        return self.path / "fluid" / name

    def solid_state(self, name: str) -> Path:
        return self.path / "solid" / f"state-{name}.npz"

    def fluid_files(self) -> dict[str, str]:
        """Every start's fluid time directory, as case files (relative path -> text)."""
        files: dict[str, str] = {}
        for name in self.times:
            root = self.fluid_dir(name)
            for path in sorted(root.rglob("*")):
                if path.is_file():
                    rel = path.relative_to(self.path / "fluid").as_posix()
                    files[f"fluid-openfoam/{rel}"] = path.read_text()
        return files

    def check(self, resolution: str, time_step: float, degree: int) -> None:
        """Refuse an env whose case is not the one the states were saved from."""
        wanted = {"resolution": resolution, "time_step": time_step, "degree": degree}
        saved = {"resolution": self.resolution, "time_step": self.time_step, "degree": self.degree}
        if any(
            saved[k] != v if k != "time_step" else not math.isclose(saved[k], v)
            for k, v in wanted.items()
        ):
            raise ValueError(
                f"{self.path / INDEX}: these starts were saved from the case {saved}, not "
                f"{wanted}; build a library for this case: {BUILD_COMMAND} --out DIR "
                f"--resolution {resolution} --time-step {time_step:g} --degree {degree}"
            )


def start_times(first: float, count: int, spacing: float) -> list[float]:
    """``count`` times ``spacing`` apart from ``first`` (s)."""
    if count < 1 or not spacing > 0 or first < 0:
        raise ValueError("starts need count >= 1, spacing > 0 and first >= 0")
    return [round(first + k * spacing, 9) for k in range(count)]


def load(path: str | Path) -> StartLibrary:
    """The library at ``path``; a missing or incomplete one is refused, naming the fix."""
    root = Path(path).expanduser().resolve()
    index = root / INDEX
    build_hint = f"build it: {BUILD_COMMAND} --out {root}"
    try:
        data = json.loads(index.read_text())
    except FileNotFoundError:
        raise FileNotFoundError(f"{index}: no library of starts here; {build_hint}") from None
    except ValueError as exc:
        raise ValueError(f"{index}: not a library of starts ({exc}); {build_hint}") from None
    library = StartLibrary(
        path=root,
        resolution=str(data["resolution"]),
        time_step=float(data["time_step"]),
        degree=int(data["degree"]),
        times=tuple(data["times"]),
        split={k: list(v) for k, v in data["split"].items()},
    )
    missing = [
        str(p)
        for name in library.times
        for p in (library.fluid_dir(name), library.solid_state(name))
        if not p.exists()
    ]
    if missing:
        raise FileNotFoundError(
            f"{index}: the library lacks {len(missing)} state(s), e.g. {missing[0]}; {build_hint}"
        )
    return library


def split(names: list[str]) -> dict[str, list[str]]:
    """The starts' split (see the module), by their time directories' names."""
    from gymprecice_openfoam.case import split_snapshots

    return split_snapshots(names, {"validation_fraction": 0.25})
