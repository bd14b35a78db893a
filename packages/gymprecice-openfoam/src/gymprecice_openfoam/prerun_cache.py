"""Share pre-run results between environments and between runs.

Each environment prepares its own copy of the case, and each would otherwise repeat the
same uncoupled pre-run to a developed flow: minutes (the quickstart) to tens of minutes
(the jet cylinder) of CPU for a result that is the same every time, paid again by every
``train``, ``evaluate`` and ``baseline``. A pre-run is a function of the case's files
before it (mesh, decomposition, fields, dictionaries; controlDict without the run's span,
which the pre-run sets itself, so episodes of any length share it), the application, the
process count, the target times, the extra arguments and the OpenFOAM installation; its
output time directories are stored under a hash of exactly those inputs, and a later
prepare with the same inputs copies them instead of running. A lock per entry makes
environments that prepare at the same time wait for the first one's pre-run instead of all
running it.

Where: ``$GYMPRECICE_CACHE_DIR/openfoam-prerun`` or ``$XDG_CACHE_HOME/gymprecice/...``
(default ``~/.cache/gymprecice/openfoam-prerun``); the solver option ``prerun_cache``
names another directory, or ``false`` turns sharing off. Deleting the directory is always
safe.
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import json
import os
import shutil
from collections.abc import Callable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

from gymprecice.plugin import ConfigError

__all__ = ["CACHE_ENV", "cache_dir", "entry_key", "locked_entry", "restore", "store"]

CACHE_ENV = "GYMPRECICE_CACHE_DIR"
_SUBDIR = "openfoam-prerun"
#: where an entry records what it holds
_INDEX = "entry.json"


def cache_dir(options: Mapping[str, Any]) -> Path | None:
    """The cache directory the solver options ask for, or ``None`` when sharing is off."""
    choice = options.get("prerun_cache", True)
    if choice is False:
        return None
    if isinstance(choice, str | os.PathLike):
        return Path(choice).expanduser()
    if choice is not True:
        raise ConfigError(
            f"solver option prerun_cache={choice!r}: use true (the default cache), false "
            "(no sharing) or a directory path"
        )
    if os.environ.get(CACHE_ENV):
        return Path(os.environ[CACHE_ENV]).expanduser() / _SUBDIR
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "gymprecice" / _SUBDIR


def entry_key(
    run_dir: Path,
    *,
    skip: Sequence[str],
    parameters: Mapping[str, Any],
    as_read: Mapping[str, Callable[[bytes], bytes]] | None = None,
) -> str:
    """Hash of every input file under ``run_dir`` (names and contents) and ``parameters``.

    ``skip``: top-level names that are not inputs (logs, earlier outputs, stores).
    ``as_read``: for a file (its path relative to ``run_dir``), what of its contents the
    pre-run depends on, hashed instead of the contents: two cases that differ only where
    the pre-run overrides the file share one entry.
    """
    as_read = as_read or {}
    digest = hashlib.sha256(json.dumps(parameters, sort_keys=True, default=str).encode())
    for path in sorted(_input_files(run_dir, set(skip))):
        name = path.relative_to(run_dir).as_posix()
        digest.update(b"\0" + name.encode() + b"\0")
        if name in as_read:
            digest.update(as_read[name](path.read_bytes()))
            continue
        with path.open("rb") as handle:
            for block in iter(lambda: handle.read(1 << 20), b""):
                digest.update(block)
    return digest.hexdigest()[:32]


def _input_files(run_dir: Path, skip: set[str]) -> Iterator[Path]:
    for entry in os.scandir(run_dir):
        if entry.name in skip:
            continue
        path = Path(entry.path)
        if entry.is_file(follow_symlinks=True):
            yield path
        elif entry.is_dir(follow_symlinks=True):
            yield from (p for p in path.rglob("*") if p.is_file())


@contextlib.contextmanager
def locked_entry(directory: Path, key: str) -> Iterator[Path]:
    """Hold the entry ``key`` exclusively; yields its path (which may not exist yet)."""
    directory.mkdir(parents=True, exist_ok=True)
    with open(directory / f"{key}.lock", "a") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            yield directory / key
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)


def store(entry: Path, run_dir: Path, written: Mapping[str, Sequence[str]], log: str) -> None:
    """Keep the time directories a pre-run ``written`` (root -> names) and its log.

    Roots are ``"."`` for the case and ``processorN`` for a decomposed run. The entry is
    assembled beside its final place and renamed, so a reader never sees half of it.
    """
    partial = entry.with_name(f"{entry.name}.partial-{os.getpid()}")
    if partial.exists():
        shutil.rmtree(partial)
    partial.mkdir(parents=True)
    for root, names in written.items():
        for name in names:
            shutil.copytree(run_dir / root / name, partial / root / name, symlinks=True)
    if (run_dir / log).is_file():
        shutil.copy2(run_dir / log, partial / log)
    index = {"written": {root: list(names) for root, names in written.items()}, "log": log}
    (partial / _INDEX).write_text(json.dumps(index, indent=1))
    os.replace(partial, entry)


def restore(entry: Path, run_dir: Path) -> dict[str, list[str]] | None:
    """Copy a stored pre-run into ``run_dir``; ``None`` when there is no usable entry."""
    try:
        index = json.loads((entry / _INDEX).read_text())
    except (OSError, ValueError):
        return None
    written: dict[str, list[str]] = index["written"]
    for root, names in written.items():
        for name in names:
            target = run_dir / root / name
            if target.exists():
                shutil.rmtree(target)
            shutil.copytree(entry / root / name, target, symlinks=True)
    log = index.get("log")
    if log and (entry / log).is_file():
        text = (entry / log).read_text(errors="replace")
        (run_dir / log).write_text(
            f"// gymprecice: pre-run restored from the shared cache {entry}\n{text}"
        )
    return written
