"""``gymprecice prepare ENV``: do now what an environment's first reset would, and keep it.

The first reset of an environment prepares each solver's case: a mesh to generate, a
pre-run to a developed flow (47 s of one core for the jet cylinder's training case, tens
of minutes for the paper's). The plugins keep what they can in their shared caches (the
OpenFOAM plugin's pre-run cache), so only the first env ever pays. This command pays it
ahead, without coupling anything: before a training, beside a set-up that is still
installing packages (``scripts/train.sh`` does so), or on a cluster's login node before
the jobs start. No preCICE is needed.

ENV is a registered environment (its id or its card's short name). It is made with its
run root in a temporary directory, each solver's case is prepared there by its plugin,
and the directory is removed: what stays is what the plugins' caches keep.

Stopped (SIGTERM, SIGINT), it stops what it started (a pre-run's solver is killed with
it), keeps nothing half written (a cache entry is stored whole or not at all) and exits
with 143 or 130.
"""

from __future__ import annotations

import argparse
import signal
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from gymprecice.tools.sketch_command import SketchRefused, env_layer, load_case, parse_env_kwargs

__all__ = ["add_prepare_parser", "cmd_prepare"]


class _Stopped(BaseException):
    """SIGTERM: unwinds like Ctrl-C, so that a running pre-run's solver is killed too."""


def add_prepare_parser(sub: Any) -> None:
    """Add ``gymprecice prepare`` to the command line's sub-parsers."""
    p = sub.add_parser(
        "prepare",
        help="prepare an environment's cases ahead (meshes, pre-runs) into the shared caches",
        description=__doc__.split("\n\n")[1].replace("\n", " "),
    )
    p.add_argument(
        "env",
        metavar="ENV",
        help="a registered environment (id or short name, e.g. jet-cylinder-fast)",
    )
    p.add_argument(
        "--env-kwargs",
        default=None,
        metavar="JSON",
        help="keyword arguments for the environment, as training gets them",
    )
    p.set_defaults(func=cmd_prepare)


def _prepare(env: Any) -> dict[str, Any]:
    """Prepare the env's run directory; each solver's case directory, by name."""
    layer = env_layer(env, lambda seen: hasattr(seen, "solver_dirs"))
    if layer is None:
        raise SketchRefused(
            "the environment prepares no solver case of gymprecice's (no solver_dirs)"
        )
    return dict(layer.solver_dirs)


def _raise_stopped(signum: int, frame: object) -> None:
    raise _Stopped(signum)


def cmd_prepare(args: argparse.Namespace) -> int:
    if Path(args.env).exists():
        print(
            f"gymprecice prepare: error: {args.env}: give a registered environment (its id or "
            "short name); a case directory is prepared by the first env made from it",
            file=sys.stderr,
        )
        return 2
    previous = signal.signal(signal.SIGTERM, _raise_stopped)
    started = time.monotonic()
    try:
        kwargs = parse_env_kwargs(args.env_kwargs)
        with tempfile.TemporaryDirectory(prefix="gymprecice-prepare-") as run_root:
            _, title, env = load_case(args.env, run_root, kwargs)
            try:
                solvers = _prepare(env)
            finally:
                env.close()
    except SketchRefused as exc:
        print(f"gymprecice prepare: error: {exc}", file=sys.stderr)
        return 2
    except _Stopped:
        print("gymprecice prepare: stopped; nothing half prepared was kept", file=sys.stderr)
        return 143
    except KeyboardInterrupt:
        print("gymprecice prepare: interrupted; nothing half prepared was kept", file=sys.stderr)
        return 130
    finally:
        signal.signal(signal.SIGTERM, previous)
    took = time.monotonic() - started
    names = ", ".join(solvers) or "none"
    print(f"gymprecice prepare: {title}: prepared in {took:.0f} s (solvers: {names})")
    return 0
