"""What a prepared OpenFOAM case is, shared by preparing, resetting and launching it.

The names of the store (``.gymprecice-openfoam/``) and of the pre-run's output, the time
directories of a case and of its ``processor*`` directories, :class:`PreparedCase` (the
record prepare leaves, loaded again by a process that did not prepare), and the few file
operations every step uses. It exists so that :mod:`.case_prepare`, :mod:`.case_reset` and
:mod:`.case_launch` read one definition of the case's layout instead of each other.
"""

from __future__ import annotations

import json
import os
import shutil
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from gymprecice.plugin import CaseError, SolverContext
from gymprecice_openfoam.mesh import processor_dirs

STORE = ".gymprecice-openfoam"
PRERUN_OUTPUT = "postProcessing.prerun"
STATE_FILE = "state.json"

#: Top-level names an episode may leave behind (removed by reset unless prepare made them).
_PRECICE_DIRS = ("precice-run", "precice-profiling", "preCICE-output", "precice-output")


def is_episode_output(name: str) -> bool:
    if name in _PRECICE_DIRS:
        return True
    if name.endswith(".xml"):
        return False
    return (
        name.startswith("log.")
        or name.endswith(".log")
        or (name.startswith("precice-") and (name.endswith((".log", ".json", ".txt"))))
    )


def time_names(root: Path) -> dict[str, float]:
    """Time directories of ``root`` (name -> value); ``constant`` and others excluded."""
    out: dict[str, float] = {}
    try:
        entries = list(os.scandir(root))
    except FileNotFoundError:
        return out
    for entry in entries:
        if not entry.is_dir():
            continue
        try:
            value = float(entry.name)
        except ValueError:
            continue
        if np.isfinite(value):
            out[entry.name] = value
    return out


def find_time(root: Path, value: float, tolerance: float) -> str | None:
    """Name of the time directory within ``tolerance`` of ``value`` (closest wins)."""
    best: tuple[float, str] | None = None
    for name, t in time_names(root).items():
        gap = abs(t - value)
        if gap <= tolerance and (best is None or gap < best[0]):
            best = (gap, name)
    return None if best is None else best[1]


def time_roots(run_dir: Path) -> list[Path]:
    """Directories holding time directories: the case and each processor directory."""
    return [run_dir, *processor_dirs(run_dir)]


def root_key(run_dir: Path, root: Path) -> str:
    return "case" if root == run_dir else root.name


@dataclass
class PreparedCase:
    """What prepare did, kept in ``solver.state`` and in ``.gymprecice-openfoam/state.json``.

    The file lets a reset work in a process that did not run prepare (a respawned env).
    """

    application: str
    np: int
    initial_time: str
    delta_t: float = 0.0
    #: root key ("case", "processor0", ...) -> time directory names after prepare
    prepared_times: dict[str, list[str]] = field(default_factory=dict)
    snapshots: list[str] = field(default_factory=list)
    split: dict[str, list[str]] = field(default_factory=dict)
    #: run-dir relative path -> [size, mtime_ns] of every file in prepared time dirs
    manifest: dict[str, list[int]] = field(default_factory=dict)
    top_level: list[str] = field(default_factory=list)
    post_dirs: list[str] = field(default_factory=list)
    coupled: bool = True

    def save(self, run_dir: Path) -> None:
        store = run_dir / STORE
        store.mkdir(exist_ok=True)
        (store / STATE_FILE).write_text(json.dumps(asdict(self), indent=1, sort_keys=True))

    @classmethod
    def load(cls, run_dir: Path) -> PreparedCase | None:
        path = run_dir / STORE / STATE_FILE
        if not path.is_file():
            return None
        return cls(**json.loads(path.read_text()))

    @property
    def tolerance(self) -> float:
        return max(1e-9, 0.5 * self.delta_t)


def prepared_state(solver: SolverContext) -> PreparedCase:
    state = solver.state.get("openfoam")
    if isinstance(state, PreparedCase):
        return state
    loaded = PreparedCase.load(Path(solver.run_dir))
    if loaded is None:
        raise CaseError(
            f"{solver.describe()}: {solver.run_dir} was not prepared (no {STORE}/{STATE_FILE}); "
            "prepare the case before reset or launch"
        )
    solver.state["openfoam"] = loaded
    return loaded


def check_run_dir(solver: SolverContext) -> Path:
    run_dir = Path(solver.run_dir).resolve()
    if run_dir == Path(solver.source_dir).resolve():
        raise CaseError(
            f"{solver.describe()}: run directory {run_dir} is the source case; gymprecice "
            "prepares and resets a copy and never writes into the source"
        )
    if not run_dir.is_dir():
        raise CaseError(f"{solver.describe()}: run directory {run_dir} does not exist")
    return run_dir


def clean_outputs(run_dir: Path, keep: set[str]) -> None:
    for entry in os.scandir(run_dir):
        if entry.name in keep or not is_episode_output(entry.name):
            continue
        remove_path(Path(entry.path))


def remove_path(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path)
    else:
        path.unlink(missing_ok=True)


def post_entries(run_dir: Path) -> set[str]:
    post = run_dir / "postProcessing"
    if not post.is_dir():
        return set()
    return {f"{fo.name}/{e.name}" for fo in post.iterdir() if fo.is_dir() for e in fo.iterdir()}


def copy_tree(src: Path, dst: Path) -> None:
    if dst.exists():
        remove_path(dst)
    shutil.copytree(src, dst, copy_function=shutil.copy2, symlinks=True)
