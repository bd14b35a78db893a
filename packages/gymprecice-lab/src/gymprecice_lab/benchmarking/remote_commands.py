"""``gymprecice`` commands as Ray tasks on any node of a cluster, no shared file system needed.

``gymprecice benchmark --ray`` trains every seed with its envs on the cluster; this module
sends the rest of its work there too: each evaluation and the baselines' sweep is one Ray
task. A task

* asks for the CPUs its solvers use (every env of the command at once) and refuses to be
  queued where no node has that many: Ray would wait for such a node for ever;
* gets its inputs shipped as archives (a policy's training directory: its top-level files,
  the model, normalizer and manifest; never its checkpoints or env runs), and the files of
  its output directory that already exist, so that a command that resumes finds them;
* runs ``python -m gymprecice ARGV --out DIR`` in a scratch directory on its node
  (``$GYMPRECICE_NODE_DIR``, else the node's temporary directory), in a process that dies
  with the task (``PR_SET_PDEATHSIG``), which in turn stops its envs and their solvers;
* brings its output directory back into the driver's, without the env runs (``envs/``)
  but with their solver logs; the driver's paths replace the node's in the JSON it wrote.
  ``remote.json`` beside them says which node ran it and how long it took.

Ctrl-C, SIGTERM or SIGHUP on the driver cancel every task (a killed task's process takes
its solvers with it). A failed command is reported with the tail of its output once all
have run; the finished ones are kept.
"""

from __future__ import annotations

import contextlib
import io
import os
import shutil
import signal
import socket
import subprocess
import sys
import tarfile
import tempfile
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from gymprecice_lab.common.ray_cluster import largest_node_cpus, too_large

#: where a task works on its node when the driver's environment does not say
NODE_DIR_ENV = "GYMPRECICE_NODE_DIR"
#: the driver's variables that reach the command (as for the Ray backend's envs)
FORWARD_PREFIX = "GYMPRECICE_"
#: an output's env runs stay on the node; these of their files come back
RUN_DIR = "envs"
_LOG_NAMES = ("log.", ".log")
TAIL_LINES = 30
#: seconds a cancelled command gets to stop its envs before SIGKILL
COMMAND_GRACE_S = 30.0


class RemoteCommandError(RuntimeError):
    """A command could not run on the cluster, or failed there (the message says which)."""


@dataclass(frozen=True)
class RemoteCommand:
    """One ``gymprecice`` command for a node.

    ``argv`` has no ``--out``: the task adds the node's copy of ``out``. Each of
    ``inputs`` is an option whose value is a driver path (a file, or a directory whose
    top-level files are shipped, with a training run's kept-model record) and becomes the
    node's copy of it.
    """

    argv: Sequence[str]
    out: Path
    what: str
    inputs: Mapping[str, Path] = field(default_factory=dict)
    cpus: float = 1.0


# -- archives -------------------------------------------------------------------------------


def pack(
    path: Path,
    *,
    top_level_only: bool = False,
    skip_runs: bool = False,
    also: Sequence[Path] = (),
) -> bytes:
    """A gzip'ed tar of ``path`` (a file, or the contents of a directory); links are
    followed. ``top_level_only``: a directory's files, not its subdirectories, but for
    the files of ``also`` (paths relative to it) where they exist. ``skip_runs``: without
    the env runs (``envs/``) except their logs."""
    buffer = io.BytesIO()
    with tarfile.open(fileobj=buffer, mode="w:gz", dereference=True) as tar:
        if path.is_file():
            tar.add(path, arcname=path.name)
        elif path.is_dir():
            for item in sorted(path.rglob("*")):
                relative = item.relative_to(path)
                if not item.is_file():
                    continue
                if top_level_only and len(relative.parts) > 1 and relative not in also:
                    continue
                if skip_runs and relative.parts[0] == RUN_DIR and not _is_log(item.name):
                    continue
                tar.add(item, arcname=str(relative))
    return buffer.getvalue()


def _is_log(name: str) -> bool:
    return name.startswith(_LOG_NAMES[0]) or name.endswith(_LOG_NAMES[1])


def unpack(blob: bytes, destination: Path) -> None:
    """Extract ``blob`` (from :func:`pack`) into ``destination``; nothing outside it."""
    destination.mkdir(parents=True, exist_ok=True)
    if not blob:
        return
    with tarfile.open(fileobj=io.BytesIO(blob), mode="r:gz") as tar:
        tar.extractall(destination, filter="data")


def _replace_paths(directory: Path, replacements: Mapping[str, str]) -> None:
    """The driver's paths for the node's in the JSON files a command wrote."""
    for path in directory.rglob("*.json"):
        text = path.read_text()
        new = text
        for old, value in replacements.items():
            new = new.replace(old, value)
        if new != text:
            path.write_text(new)


# -- on the node ----------------------------------------------------------------------------


#: ``python -c`` that asks Linux for SIGTERM when the task's worker exits (a cancelled task,
#: a lost node; PR_SET_PDEATHSIG), then runs ``gymprecice``: set after the exec, as a
#: ``preexec_fn`` is unsafe in Ray's threaded worker. The command's solvers die with it.
_BOOT = (
    "import ctypes, os, runpy, signal, sys\n"
    "ctypes.CDLL(None).prctl(1, int(signal.SIGTERM), 0, 0, 0)\n"
    "if os.getppid() != int(sys.argv.pop(1)): sys.exit('gymprecice: the Ray task is gone')\n"
    "runpy.run_module('gymprecice', run_name='__main__', alter_sys=True)\n"
)


def run_on_node(
    argv: Sequence[str],
    inputs: Mapping[str, tuple[str, bool, bytes]],
    existing_out: bytes,
    environ: Mapping[str, str],
    driver_paths: Mapping[str, str],
) -> dict[str, Any]:
    """Run one command here (the Ray task's body); its status, output archive and tail."""
    os.environ.update(environ)
    base = Path(os.environ.get(NODE_DIR_ENV) or tempfile.gettempdir())
    base.mkdir(parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix="gymprecice-command-", dir=base))
    started = time.monotonic()
    try:
        args = list(argv)
        shipped: dict[str, str] = {}
        for option, (name, is_dir, blob) in inputs.items():
            # a directory's files land in inputs/NAME/, a file as inputs/NAME
            unpack(blob, work / "inputs" / name if is_dir else work / "inputs")
            value = str(work / "inputs" / name)
            args += [option, value]
            shipped[option] = value
        out = work / "out"
        unpack(existing_out, out)
        # what a resumed command compares (its manifest's paths) must name the node's copies
        _replace_paths(
            out,
            {driver_paths[o]: v for o, v in shipped.items()} | {driver_paths["--out"]: str(out)},
        )
        args += ["--out", str(out)]
        log = work / "command.log"
        with open(log, "wb") as sink:
            # a session of its own: a group kill of Ray's worker reaches it as the SIGTERM
            # of PR_SET_PDEATHSIG, which it answers by stopping its envs, not as SIGKILL
            process = subprocess.Popen(
                [sys.executable, "-c", _BOOT, str(os.getpid()), *args],
                cwd=out,  # what its manifest records as its directory: the driver's out
                stdin=subprocess.DEVNULL,
                stdout=sink,
                stderr=subprocess.STDOUT,
                start_new_session=True,
            )
            try:
                status = _wait(process)
            finally:
                if process.poll() is None:  # the task was cancelled: stop the command
                    process.terminate()
                    try:
                        process.wait(COMMAND_GRACE_S)
                    except subprocess.TimeoutExpired:
                        process.kill()
        lines = log.read_text(errors="replace").splitlines()
        import ray

        return {
            "status": status,
            "out": pack(out, skip_runs=True) if out.is_dir() else b"",
            "tail": "\n".join(lines[-TAIL_LINES:]),
            "work": str(work),
            "shipped": shipped,
            "node_id": ray.get_runtime_context().get_node_id(),
            "host": socket.gethostname(),
            "seconds": round(time.monotonic() - started, 1),
        }
    finally:
        _kill_solvers_left(work)
        shutil.rmtree(work, ignore_errors=True)


def _wait(process: subprocess.Popen[bytes]) -> int:
    """The command's exit status, waiting in short steps: Ray's cancel of a task is an
    exception raised between two bytecodes, which a long ``waitpid`` would never reach."""
    while True:
        try:
            return process.wait(1.0)
        except subprocess.TimeoutExpired:
            continue


def _kill_solvers_left(work: Path) -> None:
    """Kill every solver a command's envs recorded and left running (a command killed
    before it could stop them)."""
    from gymprecice.env.pidregistry import kill_recorded_groups

    for registry in work.rglob(".gymprecice"):
        with contextlib.suppress(Exception):
            kill_recorded_groups(registry.parent)


# -- on the driver --------------------------------------------------------------------------


def check_fits(needs: Sequence[tuple[str, float]], cpus: float) -> None:
    """Refuse any of ``needs`` (what, CPUs on one node) that no node of ``cpus`` CPUs can
    run (Ray would queue it for ever)."""
    reason = too_large(needs, cpus)
    if reason:
        raise RemoteCommandError(reason)


def _input_archive(option: str, path: Path) -> tuple[str, bool, bytes]:
    """A driver path as its node copy: a file, or a directory's top-level files with a
    training run's kept-model record (``eval/best.json``): without it, ``--model kept``
    on the node would take the final model, and the evaluation would not be the kept
    model's."""
    from gymprecice_lab.common.kept_model import KEPT_RECORD

    if not path.exists():
        raise RemoteCommandError(f"{option} {path}: no such file or directory to ship")
    return path.name, path.is_dir(), pack(path, top_level_only=path.is_dir(), also=[KEPT_RECORD])


def run_commands(commands: Sequence[RemoteCommand], address: str) -> None:
    """Run ``commands`` as Ray tasks on the cluster at ``address``, all at once (Ray queues
    them by their CPUs); their outputs land in their ``out``. Raises
    :class:`RemoteCommandError` naming every failed command once all have run."""
    if not commands:
        return
    import ray

    owns = not ray.is_initialized()
    if owns:
        ray.init(address=address, log_to_driver=False)
    try:
        check_fits([(c.what, c.cpus) for c in commands], largest_node_cpus())
        task = ray.remote(max_retries=0)(run_on_node)
        environ = {k: v for k, v in os.environ.items() if k.startswith(FORWARD_PREFIX)}
        refs: dict[Any, RemoteCommand] = {}
        for command in commands:
            inputs = {o: _input_archive(o, Path(p)) for o, p in command.inputs.items()}
            existing = pack(command.out, skip_runs=True) if command.out.is_dir() else b""
            paths = {o: str(p) for o, p in command.inputs.items()} | {"--out": str(command.out)}
            ref = task.options(num_cpus=command.cpus).remote(
                list(command.argv), inputs, existing, environ, paths
            )
            refs[ref] = command
        failures = _collect(refs)
    finally:
        if owns and ray.is_initialized():
            ray.shutdown()
    if failures:
        raise RemoteCommandError(
            "; ".join(failures) + "; the finished ones are kept: run the same command again"
        )


def _collect(refs: dict[Any, RemoteCommand]) -> list[str]:
    """Wait for every task, bringing each output back as it finishes; cancel them all on
    Ctrl-C, SIGTERM or SIGHUP (then raise :class:`~gymprecice_lab.training.callbacks.Interrupted`
    or ``KeyboardInterrupt``)."""
    import ray
    from ray.exceptions import RayError

    from gymprecice_lab.training.callbacks import Interrupted

    # SIGTERM and SIGHUP are noted, not raised: raised inside ``ray.wait``, Ray would turn
    # them into a plain KeyboardInterrupt
    received: list[int] = []
    previous = {
        sig: signal.signal(sig, lambda signum, frame: received.append(signum))
        for sig in (signal.SIGTERM, signal.SIGHUP)
    }
    failures: list[str] = []
    pending = list(refs)
    try:
        try:
            while pending:
                if received:
                    raise Interrupted(received[0])
                ready, pending = ray.wait(pending, num_returns=1, timeout=1.0)
                if not ready:
                    continue
                command = refs[ready[0]]
                try:
                    result = ray.get(ready[0])
                except RayError as exc:  # the task's worker or node died
                    failures.append(f"{command.what}: lost on the cluster ({type(exc).__name__})")
                    continue
                _bring_back(command, result)
                if result["status"]:
                    failures.append(
                        f"{command.what}: exit status {result['status']} on {result['host']}:\n"
                        f"{result['tail']}"
                    )
                else:
                    print(
                        f"gymprecice benchmark: {command.what}: done on {result['host']} in "
                        f"{result['seconds']:.0f} s",
                        flush=True,
                    )
        except BaseException:
            _cancel(pending)
            raise
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    return failures


def _cancel(refs: list[Any]) -> None:
    """Cancel tasks: each stops its command (which stops its envs); one that has not
    finished ``COMMAND_GRACE_S`` later is killed with its worker."""
    import ray

    for ref in refs:
        with contextlib.suppress(Exception):
            ray.cancel(ref)
    if refs:
        with contextlib.suppress(Exception):
            _, refs = ray.wait(refs, num_returns=len(refs), timeout=COMMAND_GRACE_S + 5.0)
    for ref in refs:
        with contextlib.suppress(Exception):
            ray.cancel(ref, force=True)


def _bring_back(command: RemoteCommand, result: Mapping[str, Any]) -> None:
    """Unpack a task's output into its driver directory, with the driver's paths."""
    import json

    unpack(result["out"], command.out)
    work = result["work"]
    replacements = {f"{work}/out": str(command.out)}
    for option, node_path in result["shipped"].items():
        replacements[node_path] = str(Path(command.inputs[option]))
    _replace_paths(command.out, replacements)
    remote = {
        "host": result["host"],
        "node_id": result["node_id"],
        "seconds": result["seconds"],
        "status": result["status"],
        "command": ["gymprecice", *command.argv, "--out", str(command.out)],
    }
    (command.out / "remote.json").write_text(json.dumps(remote, indent=2) + "\n")
