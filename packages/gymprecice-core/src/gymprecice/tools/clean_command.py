"""``gymprecice clean``, and ``doctor``'s line about solvers left by a run that is gone.

A solver normally dies with the process that owns its env (:mod:`gymprecice.owner_watchdog`).
Where even the watchdog could not act (it was killed with its owner, or the machine was
short of memory), the solvers run on. They are found here from the per-user owner index:
each indexed owner that is gone names its run directories, whose pid registries
(:mod:`gymprecice.pidregistry`) record the process groups it started. Only processes proven
to be those groups (leader start time, launch token) count, never a process found by its
name, and a group whose processes name a live owner (a new run in the same directory) is
never touched. ``clean`` stops them (SIGTERM, then SIGKILL) and forgets the owners it has
cleaned up after.
"""

from __future__ import annotations

import argparse
import collections
import contextlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from gymprecice.env.owner_watchdog import OWNER_VARIABLE, Owner, owner_index
from gymprecice.env.pidregistry import GroupRecord, PidRegistry, kill_group_records, proven_members
from gymprecice.plugin.solver import DoctorCheck

__all__ = ["Leftover", "add_clean_parser", "clean", "find_leftovers", "leftover_check"]

#: seconds between SIGTERM and SIGKILL
DEFAULT_GRACE_S = 2.0


@dataclass(frozen=True)
class Leftover:
    """A recorded process group still running although the process that started it is gone."""

    owner: Owner
    env_dir: Path
    record: GroupRecord
    pids: tuple[int, ...]
    #: the owner's file in the index
    index_file: Path
    #: each process's command name, read when it was found (before any signal)
    commands: tuple[str, ...] = ()

    def describe(self) -> str:
        names = collections.Counter(self.commands or map(_command_name, self.pids))
        what = ", ".join(name if n == 1 else f"{n} x {name}" for name, n in names.items())
        pids = ", ".join(map(str, self.pids[:6])) + (", ..." if len(self.pids) > 6 else "")
        return (
            f"{what} (pid {pids}) in {self.env_dir}, started by gymprecice process "
            f"{self.owner.pid}, which is gone"
        )


def find_leftovers() -> tuple[list[Leftover], list[Path]]:
    """The left-overs of every gone owner of this host, and the index files of gone owners
    that left nothing (safe to forget)."""
    index = owner_index()
    alive = {path: owner.alive() for owner, _, path in index}
    in_use = {d for owner, dirs, path in index if alive[path] for d in dirs}
    leftovers: list[Leftover] = []
    finished: list[Path] = []
    for owner, dirs, path in index:
        if alive[path]:
            continue
        found = []
        for env_dir in dirs:
            if env_dir in in_use:
                continue  # a live owner runs there now: its records are its own
            try:
                records = PidRegistry(env_dir).entries()
            except OSError:
                continue
            for record in records:
                pids = _orphaned_members(record)
                if pids:
                    names = tuple(_command_name(pid) for pid in pids)
                    found.append(Leftover(owner, env_dir, record, tuple(pids), path, names))
        leftovers += found
        if not found:
            finished.append(path)
    return leftovers, finished


def _orphaned_members(record: GroupRecord) -> list[int]:
    """The proven members of ``record``'s group, unless one of them names a live owner."""
    handles = proven_members(record)
    try:
        pids = sorted(h.pid for h in handles)
    finally:
        for handle in handles:
            handle.close()
    for pid in pids:
        owner = _owner_of(pid)
        if owner is not None and owner.alive():
            return []
    return pids


def _owner_of(pid: int) -> Owner | None:
    try:
        environ = Path(f"/proc/{pid}/environ").read_bytes()
    except OSError:
        return None
    prefix = f"{OWNER_VARIABLE}=".encode()
    for item in environ.split(b"\0"):
        if item.startswith(prefix):
            return Owner.parse(item[len(prefix) :].decode(errors="replace"), sep=":")
    return None


def _command_name(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/comm").read_text().strip() or "?"
    except OSError:
        return "?"


def clean(grace: float = DEFAULT_GRACE_S) -> tuple[list[Leftover], list[Leftover]]:
    """Stop every left-over group; ``(stopped, survivors)``. Owners left with nothing
    running are dropped from the index."""
    leftovers, finished = find_leftovers()
    survivors: list[Leftover] = []
    by_dir: dict[Path, list[Leftover]] = collections.defaultdict(list)
    for leftover in leftovers:
        by_dir[leftover.env_dir].append(leftover)
    for env_dir, found in by_dir.items():
        records = [leftover.record for leftover in found]
        _, alive = kill_group_records(records, grace)
        survivors += [leftover for leftover in found if leftover.record in alive]
        with contextlib.suppress(OSError):
            PidRegistry(env_dir).remove_records(
                lambda r, rs=records, a=alive: r in rs and r not in a
            )
    kept = {leftover.index_file for leftover in survivors}
    for path in {*finished, *(leftover.index_file for leftover in leftovers)} - kept:
        with contextlib.suppress(OSError):
            path.unlink()
    return [x for x in leftovers if x not in survivors], survivors


# -- the command and doctor's line -----------------------------------------------------------


def add_clean_parser(sub: Any) -> None:
    p = sub.add_parser(
        "clean",
        help="stop solvers left running by a gymprecice process that is gone (after a crash)",
        description=(
            "Stop the solver processes that a killed gymprecice process (kill -9, the OOM "
            "killer, a job's time limit) left running. Only processes proven to be "
            "gymprecice's own, by their run directory's record and start time, are stopped."
        ),
    )
    p.add_argument(
        "--dry-run", action="store_true", help="list what would be stopped, stop nothing"
    )
    p.add_argument(
        "--grace",
        type=float,
        default=DEFAULT_GRACE_S,
        metavar="S",
        help=f"seconds between SIGTERM and SIGKILL (default {DEFAULT_GRACE_S:g})",
    )
    p.set_defaults(func=cmd_clean)


def cmd_clean(args: argparse.Namespace) -> int:
    if args.dry_run:
        leftovers, _ = find_leftovers()
        for leftover in leftovers:
            print(f"gymprecice clean: would stop {leftover.describe()}")
        if not leftovers:
            print(
                "gymprecice clean: nothing to clean: no solver of a gone gymprecice run is running"
            )
        return 0
    stopped, survivors = clean(args.grace)
    for leftover in stopped:
        print(f"gymprecice clean: stopped {leftover.describe()}")
    for leftover in survivors:
        print(f"gymprecice clean: could not stop {leftover.describe()} (it survived SIGKILL)")
    if not stopped and not survivors:
        print("gymprecice clean: nothing to clean: no solver of a gone gymprecice run is running")
    return 1 if survivors else 0


def leftover_check() -> DoctorCheck:
    """``doctor``'s line: solvers whose gymprecice process is gone, and what to do."""
    name = "leftover solvers"
    try:
        leftovers, _ = find_leftovers()
    except OSError as exc:  # pragma: no cover - an unreadable state directory
        return DoctorCheck(name, True, f"could not look: {exc}")
    if not leftovers:
        return DoctorCheck(name, True, "none: no solver of a gone gymprecice run is running")
    return DoctorCheck(
        name,
        False,
        "; ".join(leftover.describe() for leftover in leftovers),
        "run `gymprecice clean` to stop them (it stops only processes proven to be gymprecice's)",
    )
