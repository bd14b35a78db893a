"""Where a study's ``--n-jobs`` workers run: processes on this machine, or Ray tasks.

A worker is the search's own command with ``--n-jobs 1``, its share of the trials and the
study's storage: it runs trials of the one study until the study has ``--trials``, each
trial a ``gymprecice train`` child of its own (:mod:`gymprecice_lab.training.tune`). The
workers share nothing but the storage, so they can run anywhere that reaches it:

* **here** (``--n-jobs N``): N processes, each ended with its parent;
* **on a Ray cluster** (``--ray auto|ADDRESS``): each worker is a Ray task that asks for
  ``--n-envs`` CPUs on one node and runs the worker command there, so a cluster runs as
  many trials at once as it has room for. Each worker runs in the search's directory,
  which the nodes must share (a shared home or file system: the command's relative
  paths, ``--hyperparams`` and ``--out``, mean the same there); the study must be in a
  storage every node reaches (``--storage postgresql://...``, or the default SQLite file
  in that shared directory). A trial's run directory is written by the node that
  trains it. The report (``best_hyperparams.yml``, ``tune.json``,
  the figures) is written here from the study once every worker is done.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from collections.abc import Sequence

__all__ = [
    "NODE_VARIABLE",
    "SHARE_VARIABLE",
    "WORKER_VARIABLE",
    "run_workers_here",
    "run_workers_on_ray",
]

#: the environment variable that tells a worker its index (0, 1, ...)
WORKER_VARIABLE = "GYMPRECICE_TUNE_WORKER"
#: the environment variable that tells a worker how many trials are its share
SHARE_VARIABLE = "GYMPRECICE_TUNE_SHARE"
#: the environment variable that tells a worker on Ray the id of its node (recorded with
#: each of its trials as the user attribute ``ray_node``)
NODE_VARIABLE = "GYMPRECICE_TUNE_NODE"


def worker_commands(
    argv: Sequence[str], trials: int, n_jobs: int, storage: str, name: str, todo: int
) -> list[tuple[list[str], int]]:
    """The command of each worker that has trials to run, with its share of the ``todo``
    trials: the search's ``argv`` (without ``gymprecice``) with one job, the study's
    storage and name, and no progress bar. The shares add up to ``todo``, so the workers
    together run that many trials, not one more each."""
    commands = []
    for k in range(n_jobs):
        share = todo // n_jobs + (1 if k < todo % n_jobs else 0)
        if not share:
            continue
        commands.append(
            (
                [
                    sys.executable,
                    "-m",
                    "gymprecice",
                    *_without(argv, ("--n-jobs", "--trials", "--storage", "--ray")),
                    "--n-jobs",
                    "1",
                    "--trials",
                    str(trials),
                    "--storage",
                    storage,
                    "--study-name",
                    name,
                    "--no-progress-bar",
                ],
                share,
            )
        )
    return commands


def run_workers_here(commands: list[tuple[list[str], int]]) -> None:
    """Each worker a process here, ended with this one; returns when all are done."""
    workers = [
        subprocess.Popen(
            cmd,
            preexec_fn=die_with_parent,
            env={**os.environ, WORKER_VARIABLE: str(k), SHARE_VARIABLE: str(share)},
        )
        for k, (cmd, share) in enumerate(commands)
    ]
    for worker in workers:
        worker.wait()


def run_workers_on_ray(
    commands: list[tuple[list[str], int]], address: str, cpus: float
) -> list[str]:
    """Each worker a Ray task of ``cpus`` CPUs at ``address``; one line per worker (its
    node and exit status, or that the node lacks this directory) once all are done. Ray
    is initialised here and shut down."""
    import ray

    if not ray.is_initialized():
        ray.init(address=address, log_to_driver=False)
    try:
        task = ray.remote(num_cpus=cpus, max_retries=0)(_run_worker)
        cwd = os.getcwd()
        refs = [task.remote(cmd, k, share, cwd) for k, (cmd, share) in enumerate(commands)]
        done = ray.get(refs)
    finally:
        ray.shutdown()
    return [
        f"worker {k}: Ray node {node[:12]}, "
        + (f"exit status {status}" if status is not None else f"not run: {cwd} is not there")
        for k, (node, status) in enumerate(done)
    ]


def _run_worker(cmd: list[str], index: int, share: int, cwd: str) -> tuple[str, int | None]:
    """A worker on a Ray node: the command, in the search's directory, with its index and
    its node's id; ``None`` for a node that lacks the directory (a Ray task: module level,
    so it pickles by reference)."""
    import ray

    node = ray.get_runtime_context().get_node_id()
    if not os.path.isdir(cwd):  # the nodes must share the search's directory
        return node, None
    env = {
        **os.environ,
        WORKER_VARIABLE: str(index),
        SHARE_VARIABLE: str(share),
        NODE_VARIABLE: node,
    }
    status = subprocess.run(cmd, cwd=cwd, env=env, preexec_fn=die_with_parent).returncode
    return node, status


def die_with_parent() -> None:
    """In a child, before it runs: SIGTERM when this process dies (``PR_SET_PDEATHSIG``)."""
    import ctypes

    libc = ctypes.CDLL(None, use_errno=True)
    libc.prctl(1, int(signal.SIGTERM), 0, 0, 0)


def _without(argv: Sequence[str], flags: tuple[str, ...]) -> list[str]:
    """``argv`` without ``flags`` and their values (``--flag V`` or ``--flag=V``)."""
    out: list[str] = []
    skip = False
    for arg in argv:
        if skip:
            skip = False
            continue
        if arg in flags:
            skip = True
            continue
        if any(arg.startswith(f"{flag}=") for flag in flags):
            continue
        out.append(arg)
    return out
