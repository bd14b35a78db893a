"""Each environment's own run directory and preCICE exchange directory.

N environments must reset concurrently without a global lock, so each gets a full, real
copy of the case (never symlinks into the pristine case, which would let one env's solver
write into every other env's files) and its own preCICE exchange directory, written into
its own copy of the preCICE configuration. Solvers refer to the configuration by a relative
path, so they pick up the env's copy without being told.
"""

from __future__ import annotations

import contextlib
import fcntl
import itertools
import os
import shutil
from dataclasses import dataclass
from pathlib import Path

from gymprecice.env.config import GymPreciceConfig
from gymprecice.env.pidregistry import kill_recorded_groups
from gymprecice.plugin.errors import ConfigError
from gymprecice.plugin.precice_xml import write_with_exchange_directory

MARKER = ".gymprecice"
EXCHANGE_DIR_NAME = "precice-exchange"
_NEVER_COPIED = {"__pycache__", ".git", MARKER}


@dataclass(frozen=True)
class RunDirectory:
    """Where one env runs: its root, its solvers' directories and its preCICE files."""

    root: Path
    exchange_dir: Path
    precice_config_file: Path

    @property
    def state_dir(self) -> Path:
        """gymprecice's own bookkeeping (pid registry, worker log)."""
        return self.root / MARKER

    def solver_dir(self, relative: str) -> Path:
        return self.root / relative


def env_root(config: GymPreciceConfig, env_index: int, run_root: str | Path | None) -> Path:
    base = Path(run_root) if run_root is not None else Path(config.model.environment.run_root)
    if not base.is_absolute():
        base = Path.cwd() / base
    return (base / f"env_{env_index}").resolve()


class EnvIndexClaim:
    """An env index held by one live env: an ``flock`` on ``<run_root>/.env_<i>.lock``."""

    def __init__(self, index: int, fd: int) -> None:
        self.index = index
        self._fd: int | None = fd

    def release(self) -> None:
        if self._fd is not None:
            with contextlib.suppress(OSError):
                os.close(self._fd)  # closing the descriptor drops the lock
            self._fd = None

    def __del__(self) -> None:
        self.release()


def claim_env_index(base: Path, prefer: int | None = None) -> EnvIndexClaim:
    """Hold the lowest free env index under the run root ``base`` (``prefer`` first).

    The lock is per open file, so two envs of one process exclude each other as well as
    envs of other processes; it vanishes with the process that held it.
    """
    base.mkdir(parents=True, exist_ok=True)
    candidates = (
        itertools.count() if prefer is None else itertools.chain([prefer], itertools.count())
    )
    for index in candidates:
        fd = os.open(base / f".env_{index}.lock", os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            continue
        return EnvIndexClaim(index, fd)
    raise AssertionError("unreachable")


def create_run_directory(
    config: GymPreciceConfig, env_index: int, run_root: str | Path | None = None
) -> RunDirectory:
    """Make ``<run_root>/env_<idx>`` as a fresh copy of the case directory.

    The copy is made under a hidden name beside it and renamed into place, and an old
    directory is renamed away before it is deleted: a command killed at any instant leaves
    either a whole run directory with its marker or none, never a half-copied one that
    the next run would have to refuse as foreign. The hidden leftovers of such a kill are
    deleted by the next run of the same env index.

    A previous run directory of the same env is replaced only when it carries gymprecice's
    marker; any other existing directory is left alone and reported, so a mistyped
    ``run_root`` can never delete a user's data. What the old directory's pid registry
    still records (solvers of an env process that died) is killed before the registry is
    deleted with it; otherwise they would run on, unrecorded, in a deleted directory.
    """
    root = env_root(config, env_index, run_root)
    case = config.case_dir
    if root == case or case.is_relative_to(root):
        raise ConfigError(
            f"{config.where()}: environment.run_root puts env {env_index}'s run directory at "
            f"{root}, which contains the case itself; choose a run_root outside the case"
        )
    staging, trash = _staging_dir(root), _trash_dir(root)
    for leftover in (staging, trash):  # of a command killed while it made or removed root
        if leftover.exists():
            shutil.rmtree(leftover)
    if root.exists():
        if not (root / MARKER).is_dir():
            raise ConfigError(
                f"{root} exists and was not made by gymprecice; refusing to replace it. "
                "Move it away or set environment.run_root to another directory."
            )
        kill_recorded_groups(root, grace=config.model.timeouts.kill_grace)
        os.rename(root, trash)
        shutil.rmtree(trash)
    root.parent.mkdir(parents=True, exist_ok=True)
    ignore_below_case = _ignored_run_roots(case, root)
    shutil.copytree(
        case,
        staging,
        symlinks=False,
        ignore=lambda directory, names: [
            n
            for n in names
            if n in _NEVER_COPIED or (Path(directory) / n).resolve() in ignore_below_case
        ],
    )
    (staging / MARKER).mkdir(exist_ok=True)
    (staging / EXCHANGE_DIR_NAME).mkdir(exist_ok=True)
    exchange = root / EXCHANGE_DIR_NAME  # the path the solvers will see, after the rename
    precice_file = root / config.precice_file.relative_to(case)
    write_with_exchange_directory(
        config.precice_file, staging / config.precice_file.relative_to(case), exchange
    )
    os.rename(staging, root)
    return RunDirectory(root=root, exchange_dir=exchange, precice_config_file=precice_file)


def _staging_dir(root: Path) -> Path:
    """Where ``root`` is copied before it is renamed into place."""
    return root.with_name(f".{root.name}.new")


def _trash_dir(root: Path) -> Path:
    """Where an old ``root`` is renamed before it is deleted."""
    return root.with_name(f".{root.name}.old")


def _ignored_run_roots(case: Path, root: Path) -> set[Path]:
    """Run roots that live inside the case directory must not be copied into each env."""
    run_root = root.parent.resolve()
    return {run_root} if run_root.is_relative_to(case) else set()
