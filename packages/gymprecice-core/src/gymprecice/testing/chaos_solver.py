"""The solver of the chaos case: apply an armed fault, then become the scripted partner.

:func:`gymprecice.testing.chaos.write_case` copies this file into the case's solver
directory as ``chaos_solver.py``. ``python chaos_solver.py run -- <partner args>`` takes
the fault armed for this env (:func:`gymprecice.testing.chaos.inject`, phase ``"run"``),
applies it, and ``exec``s ``python -m gymprecice.testing.partner <partner args>`` (plus
fault flags); ``python chaos_solver.py reset`` is the case's reset step: it takes a
``"reset"`` fault and checks the mesh's patches like a solver utility would. A fault is
consumed by exactly one launch (an atomic rename), so the env's next episode is healthy.

Imports only the standard library and runs as a file, not with ``-m`` (which would import
the gymprecice package): it starts twice per episode and must start fast. The partner gets
``PYTHONUNBUFFERED=1`` so that its log grows as it runs (log growth is what the Adapter's
progress watchdog sees).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import signal
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

__all__ = ["COEFFICIENTS", "FAULTS_VARIABLE", "PATCHES", "corrupt_output", "fault_path", "main"]

#: Environment variable naming the directory where armed faults wait.
FAULTS_VARIABLE = "GYMPRECICE_CHAOS_DIR"
#: The solver's drag output (written by the partner with ``--write-outputs .``).
COEFFICIENTS = Path("postProcessing", "forceCoeffs", "0", "coefficient.dat")
#: Patches the reset step requires in ``mesh/boundary``.
PATCHES = ("cylinder", "jet1", "jet2", "inlet", "outlet")


def fault_path(faults_dir: str | os.PathLike[str], env_index: int | str, phase: str) -> Path:
    """Where the fault armed for ``phase`` of env ``env_index`` waits."""
    return Path(faults_dir) / f"env_{env_index}.{phase}.json"


def _take(phase: str) -> dict[str, Any] | None:
    """Consume the armed fault of this env and phase, if any (exactly once)."""
    directory = os.environ.get(FAULTS_VARIABLE)
    index = os.environ.get("GYMPRECICE_ENV_INDEX")
    if not directory or index is None:
        return None
    path = fault_path(directory, index, phase)
    taken = path.with_name(f"{path.name}.taken.{os.getpid()}")
    try:
        os.rename(path, taken)
    except FileNotFoundError:
        return None
    return json.loads(taken.read_text())


def corrupt_output(solver_dir: str | os.PathLike[str]) -> Path:
    """Replace the solver's forceCoeffs file with garbage (a torn or corrupted write)."""
    path = Path(solver_dir) / COEFFICIENTS
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(b"\x00\x00\xff\xfe garbage \x00 1.0e+ nan nan\n")
    return path


def _launch(partner_args: Sequence[str]) -> int:
    fault = _take("run") or {}
    kind = fault.get("fault")
    argv = [sys.executable, "-m", "gymprecice.testing.partner", *partner_args]
    window = int(fault.get("window", 0))
    if kind == "kill":
        if window == 0:
            print("[chaos] fault: SIGKILL before connecting", flush=True)
            os.kill(os.getpid(), signal.SIGKILL)
        argv += ["--crash-at-window", str(window)]
    elif kind == "diverge":
        argv += ["--diverge-at-window", str(window)]
    elif kind == "stop":
        print("[chaos] fault: SIGSTOP before connecting", flush=True)
        os.kill(os.getpid(), signal.SIGSTOP)
    elif kind == "exit":
        argv += ["--crash-at-window", str(window), "--exit-code", str(fault.get("code", 1))]
    elif kind == "corrupt-output":
        corrupt_output(Path.cwd())
        print("[chaos] fault: corrupt forceCoeffs output", flush=True)
    elif kind == "disk-full":
        used = os.fstat(sys.stdout.fileno()).st_size
        limit = used + int(fault.get("headroom", 0))
        print(f"[chaos] fault: disk full after {limit} bytes per file", flush=True)
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # writes fail with EFBIG instead
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
    elif kind is not None:
        print(f"[chaos] unknown fault {kind!r}", file=sys.stderr, flush=True)
        return 2
    # A line now: the Adapter's progress watchdog counts log growth, and the partner
    # takes a while to import before preCICE prints anything.
    print(f"[chaos] starting {' '.join(argv[1:4])}", flush=True)
    os.environ["PYTHONUNBUFFERED"] = "1"
    os.execv(sys.executable, argv)
    return 0  # not reached


def _reset() -> int:
    fault = _take("reset") or {}
    boundary = Path("mesh", "boundary")
    if fault.get("fault") == "bad-case":
        patch = fault.get("patch", "jet1")
        text = boundary.read_text()
        boundary.write_text(text.replace(f"{patch}\n{{\n    type patch;\n}}\n", ""))
    try:
        text = boundary.read_text()
    except OSError as exc:
        print(f"--> FOAM FATAL ERROR: cannot read {boundary}: {exc}", file=sys.stderr)
        return 1
    present = {line.strip() for line in text.splitlines()}
    missing = [p for p in PATCHES if p not in present]
    if missing:
        print(
            f"--> FOAM FATAL ERROR: Cannot find patch {missing[0]!r} in {boundary.resolve()}; "
            f"the mesh has {sorted(present & set(PATCHES))}",
            file=sys.stderr,
            flush=True,
        )
        return 1
    print(f"[chaos] reset: mesh has all {len(PATCHES)} patches", flush=True)
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="chaos_solver.py")
    parser.add_argument("mode", choices=("run", "reset"))
    parser.add_argument("partner_args", nargs=argparse.REMAINDER)
    args = parser.parse_args(argv)
    if args.mode == "reset":
        return _reset()
    rest = list(args.partner_args)
    if rest and rest[0] == "--":
        rest = rest[1:]
    return _launch(rest)


if __name__ == "__main__":
    sys.exit(main())
