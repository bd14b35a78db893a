"""Running lab commands from lab commands: ``benchmark`` and ``time-to-floor`` are made of them.

``benchmark`` trains with ``gymprecice train``, evaluates with ``gymprecice evaluate`` and
runs the baselines with ``gymprecice sweep``; ``time-to-floor`` evaluates checkpoints. Each
piece is the ordinary command, parsed by the same parsers (so with the same defaults) and
run here or ``workers`` at once in spawned processes, its output directory its record:
:func:`evaluated` tells a finished evaluation of a model from one still to run, so a
stopped composite command resumes where it stopped. A worker process dies with the command
that started it (:func:`die_with_parent`): a command killed outright (SIGKILL, the OOM
killer, a job's time limit) leaves no worker computing on into the directories that the
same command, run again, works in.
"""

from __future__ import annotations

import argparse
import contextlib
import ctypes
import json
import os
import signal
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

__all__ = [
    "CommandFailed",
    "command_status",
    "die_with_parent",
    "evaluated",
    "exit_status_of",
    "parse_command",
    "run_commands",
    "run_in_pool",
]


class CommandFailed(SystemExit):
    """Bad input or a failed piece: one line on stderr, ``gymprecice COMMAND: message``,
    exit status 2 (input) or 1 (a piece failed)."""

    def __init__(self, command: str, message: str, status: int = 2) -> None:
        print(f"gymprecice {command}: {message}", file=sys.stderr)
        super().__init__(status)


def parse_command(argv: Sequence[str]) -> argparse.Namespace:
    """``argv`` parsed exactly as ``gymprecice ARGV`` would parse it: by the ``gymprecice``
    command line itself, with every plugin's commands (the lab's among them)."""
    from gymprecice.tools.cli import build_parser

    return build_parser().parse_args(list(argv))


def command_status(argv: list[str]) -> int:
    """The exit status of ``gymprecice ARGV`` run in this process (module-level, so that
    a worker process can run it)."""
    ns = parse_command(argv)
    return int(ns.func(ns) or 0)


def exit_status_of(call: Callable[..., Any], *args: Any) -> int:
    """``call(*args)`` in a pool's worker as an exit status: a ``SystemExit`` (a refusal,
    a failed seed) becomes its status, its message said on stderr, as a worker that
    raised would never answer."""
    try:
        return int(call(*args) or 0)
    except SystemExit as exc:
        if isinstance(exc.code, int):
            return exc.code
        print(exc.code, file=sys.stderr, flush=True)
        return 1


def evaluated(run: Path, model: Path) -> bool:
    """Whether ``run`` holds a finished ``gymprecice evaluate`` of ``model``: its summary,
    and a manifest recording that model's SHA-256 and the result.

    The evaluation writes its manifest when it starts and again, with the result, once
    ``summary.json`` is whole; an evaluation killed before the end leaves the first
    manifest (and perhaps an earlier evaluation's summary, or a summary cut short), so
    without the result it is not finished.
    """
    from gymprecice_lab.common.manifest import file_sha256

    try:
        manifest = json.loads((run / "manifest.json").read_text())
    except (OSError, ValueError):
        return False
    return (
        (run / "summary.json").is_file()
        and manifest.get("result") is not None
        and manifest.get("settings", {}).get("model_sha256") == file_sha256(model)
    )


def die_with_parent(parent: int) -> None:
    """Run first in a worker process: SIGKILL it when its parent, ``parent``, dies.

    A worker (``spawn``) does not die with the command that started it: killed outright,
    the command would leave its workers running their evaluations or rollouts to the end
    (their solvers with them), writing into the directories the rerun of the command
    works in. Linux's ``PR_SET_PDEATHSIG`` ends them (their own solvers then die with
    them, :mod:`gymprecice.owner_watchdog`); a parent that died before the request took
    effect is seen by the worker's parent no longer being ``parent``. The request holds
    while the *thread* that started the worker lives: for a worker started from a thread
    that may end first, :func:`_die_with_pool_parent`.
    """
    if sys.platform.startswith("linux"):
        with contextlib.suppress(OSError, AttributeError):
            pr_set_pdeathsig = 1
            ctypes.CDLL(None, use_errno=True).prctl(pr_set_pdeathsig, int(signal.SIGKILL), 0, 0, 0)
    if os.getppid() != parent:
        os._exit(1)


def _die_with_pool_parent(parent: int) -> None:
    """:func:`die_with_parent` for a pool's worker: a thread of the worker watches its
    parent *process* (within a second) instead of ``PR_SET_PDEATHSIG``.

    A pool with ``maxtasksperchild=1`` starts a new worker from its worker-handler thread
    whenever one finishes its job while others still run. That thread ends once the pool
    has every result, before the idle new worker has read the pool's stop sentinel:
    ``PR_SET_PDEATHSIG`` would SIGKILL that worker while it holds the lock of the pool's
    task queue, and the pool's clean-up would wait for that lock for ever (the command
    hung after its last job, e.g. a benchmark's seeds that end at different times).
    """
    import threading
    import time

    if os.getppid() != parent:
        os._exit(1)

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(1.0)
        os.kill(os.getpid(), signal.SIGKILL)

    threading.Thread(target=watch, name="die-with-parent", daemon=True).start()


def _worker_status(argv: list[str]) -> int:
    """:func:`command_status` in a pool's worker."""
    return exit_status_of(command_status, argv)


def run_commands(
    commands: list[tuple[list[str], str]], workers: int, command: str = "benchmark"
) -> None:
    """Run ``gymprecice`` commands (``(argv, what)``), ``workers`` at once in their own
    processes (one: here, in turn). Every command runs even if one fails; then the
    failures are reported (:class:`CommandFailed` of ``command``). Ctrl-C, SIGTERM or
    SIGHUP stop every worker (and so its solvers) before returning."""
    if workers <= 1 or len(commands) <= 1:
        for argv, what in commands:
            status = command_status(argv)
            if status:
                raise CommandFailed(command, f"{what} failed (exit status {status})", 1)
        return
    jobs = [((argv,), what) for argv, what in commands]
    run_in_pool(_worker_status, jobs, workers, command)


def run_in_pool(
    task: Callable[..., int],
    jobs: list[tuple[tuple[Any, ...], str]],
    workers: int,
    command: str = "benchmark",
) -> None:
    """Run ``task(*args)`` for every job, ``workers`` at once in spawned processes; a
    non-zero status or a crash is a failure, reported with the others once all ran."""
    import multiprocessing

    from gymprecice_lab.training.callbacks import stop_signals_interrupt

    context = multiprocessing.get_context("spawn")  # never fork a process holding threads
    failures = []
    with stop_signals_interrupt():
        pool = context.Pool(
            min(workers, len(jobs)),
            initializer=_die_with_pool_parent,
            initargs=(os.getpid(),),
            maxtasksperchild=1,
        )
        try:
            pending = [(pool.apply_async(task, args), what) for args, what in jobs]
            for result, what in pending:
                try:
                    status = result.get()
                except Exception as exc:  # a crashed command: reported with the others
                    failures.append(f"{what}: {type(exc).__name__}: {exc}")
                else:
                    if status:
                        failures.append(f"{what}: exit status {status}")
        except BaseException:
            pool.terminate()  # SIGTERM to every worker; their solvers' supervisors follow
            raise
        else:
            pool.close()
        finally:
            pool.join()
    if failures:
        raise CommandFailed(
            command,
            f"{'; '.join(failures)}; the finished ones are kept: run the same command again",
            1,
        )
