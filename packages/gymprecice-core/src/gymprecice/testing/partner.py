"""A small scripted solver participant: ``python -m gymprecice.testing.partner``.

Core and plugin tests need a coupling partner that behaves like a solver (provides its
mesh, reads the controller's data, advances, writes back, logs progress, sometimes dies)
but starts in a fraction of a second and is deterministic. This is it; the physics comes
from a flow class (:mod:`gymprecice.testing.flows`). It speaks only the pyprecice v3 API,
so ``--library precice`` runs the very same loop against real preCICE.

Usage::

    python -m gymprecice.testing.partner --config precice-config.xml \\
        --participant Fluid \\
        [--flow gymprecice.testing.flows:CylinderFlow] [--option KEY=VALUE ...] \\
        [--library gymprecice.testing.fake_precice|precice] [--dt SECONDS] \\
        [--crash-at-window N] [--hang-at-window N] [--diverge-at-window N] \\
        [--exit-code CODE] \\
        [--step-sleep SECONDS] [--write-outputs DIR [--write-every-step]]

One line per completed time window goes to stdout (``[Fluid] window 3 t=0.03 Cd=...``),
so the log grows exactly as the run progresses. Fault injection, at window ``N`` (``0`` is
before ``initialize()``, ``N >= 1`` right after the ``N``-th window completed):

* ``--crash-at-window N``: die by ``SIGKILL`` (no message, like a segfaulting solver); with
  ``--exit-code C`` instead print ``FATAL ERROR`` to stderr and exit with status ``C``.
* ``--hang-at-window N``: print a line, then sleep forever (a deadlocked solver).
* ``--diverge-at-window N``: diverge as a CFD solver does: print a Courant number that
  has blown up and OpenFOAM's ``Floating point exception`` line, then exit with status
  136 (128 + SIGFPE, what a shell reports for a solver killed by its FPE trap).
* ``--exit-code C`` alone: finish the run normally, then report an error and exit with ``C``.
* ``--step-sleep S``: sleep ``S`` seconds per time step (emulates a CFD step's cost).

Outputs (``--write-outputs DIR``): by default the flow appends one row per completed time
window, after the window's ``advance``. ``--write-every-step`` writes one row per solver
step (at the step's end time, ``t + dt``) *before* ``advance``, as OpenFOAM's function
objects (probes, forceCoeffs) listed before the preCICE adapter do. A solver that subcycles
(``--dt``) in a window then writes every substep, and a second participant of a serial
scheme, whose window-end ``advance`` blocks until the first participant's next window, has
written its rows before it waits (with the default, the first participant would wait for
rows that come only after its own next ``advance``: a deadlock). With implicit coupling
every iteration's rows are written, as OpenFOAM does.

Fields (``env.render()``): when core sets ``GYMPRECICE_FIELDS`` (the env renders), the
partner writes each named field of its flow (:meth:`~gymprecice.testing.flows.Flow.field`)
to ``gymprecice-fields/<name>.npz`` at time 0 and on the last solver step of every
window, before ``advance`` (so in a serial scheme the file is there when the controller
gets the window's data). A field the flow does not know ends the partner at once, with
the names it knows in its log; without the variable nothing is written.
"""

from __future__ import annotations

import argparse
import importlib
import os
import signal
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from gymprecice.plugin.fields import requested_fields, write_field_file
from gymprecice.plugin.precice_xml import load_precice_config

__all__ = ["DEFAULT_FLOW", "DEFAULT_LIBRARY", "command", "load_flow", "main", "run"]

DEFAULT_FLOW = "gymprecice.testing.flows:CylinderFlow"
DEFAULT_LIBRARY = "gymprecice.testing.fake_precice"


def command(
    config: str | os.PathLike[str],
    participant: str,
    *,
    flow: str | None = None,
    library: str | None = None,
    options: dict[str, Any] | None = None,
    python: str | None = None,
    **flags: Any,
) -> list[str]:
    """The argv that runs a partner, for ``subprocess`` or a solver of kind ``command``.

    ``flags`` are the remaining command-line options in Python spelling, e.g.
    ``crash_at_window=3, exit_code=1, step_sleep=0.01, write_outputs=".", dt=0.001,
    write_every_step=True``.
    """
    argv = [python or sys.executable, "-m", "gymprecice.testing.partner"]
    argv += ["--config", str(config), "--participant", participant]
    if flow:
        argv += ["--flow", flow]
    if library:
        argv += ["--library", library]
    for key, value in (options or {}).items():
        argv += ["--option", f"{key}={value}"]
    for key, value in flags.items():
        if value is None or value is False:
            continue
        argv.append("--" + key.replace("_", "-"))
        if value is not True:
            argv.append(str(value))
    return argv


def load_flow(spec: str) -> type:
    """``"package.module:ClassName"`` -> the class."""
    module_name, _, class_name = spec.partition(":")
    if not class_name:
        raise SystemExit(f"--flow must look like 'package.module:ClassName', got {spec!r}")
    module = importlib.import_module(module_name)
    try:
        return getattr(module, class_name)
    except AttributeError:
        raise SystemExit(f"--flow: module {module_name!r} has no class {class_name!r}") from None


def _parse(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog="python -m gymprecice.testing.partner",
        description="A scripted preCICE participant for tests (see the module docstring).",
    )
    parser.add_argument("--config", required=True, help="preCICE configuration file")
    parser.add_argument("--participant", required=True, help="participant name in the config")
    parser.add_argument("--flow", default=DEFAULT_FLOW, help="flow class, 'module:Class'")
    parser.add_argument(
        "--option", action="append", default=[], metavar="KEY=VALUE", help="flow option"
    )
    parser.add_argument(
        "--library", default=DEFAULT_LIBRARY, help="module imported as precice (default: double)"
    )
    parser.add_argument("--dt", type=float, default=None, help="solver time step (subcycling)")
    parser.add_argument("--crash-at-window", type=int, default=None, metavar="N")
    parser.add_argument("--hang-at-window", type=int, default=None, metavar="N")
    parser.add_argument("--diverge-at-window", type=int, default=None, metavar="N")
    parser.add_argument("--exit-code", type=int, default=None, metavar="CODE")
    parser.add_argument("--step-sleep", type=float, default=0.0, metavar="SECONDS")
    parser.add_argument("--write-outputs", default=None, metavar="DIR")
    parser.add_argument(
        "--write-every-step",
        action="store_true",
        help="write output rows after every solver step, before advance (OpenFOAM-like)",
    )
    return parser.parse_args(argv)


def _options(pairs: Sequence[str]) -> dict[str, str]:
    out = {}
    for pair in pairs:
        key, sep, value = pair.partition("=")
        if not sep:
            raise SystemExit(f"--option must look like KEY=VALUE, got {pair!r}")
        out[key.strip()] = value.strip()
    return out


class _Faults:
    """The injected failures, checked once per completed window (and once before start)."""

    def __init__(self, args: argparse.Namespace, name: str) -> None:
        self.crash_at = args.crash_at_window
        self.hang_at = args.hang_at_window
        self.diverge_at = args.diverge_at_window
        self.exit_code = args.exit_code
        self.name = name

    def check(self, window: int) -> None:
        if self.diverge_at is not None and window == self.diverge_at:
            print(f"Courant Number mean: 3.1e+12 max: 8.7e+15 (window {window})", flush=True)
            sys.stderr.write(f"[{self.name}] Floating point exception (window {window})\n")
            sys.stderr.flush()
            os._exit(136)
        if self.hang_at is not None and window == self.hang_at:
            print(f"[{self.name}] hanging at window {window}", flush=True)
            while True:
                time.sleep(3600.0)
        if self.crash_at is not None and window == self.crash_at:
            sys.stdout.flush()
            if self.exit_code is not None:
                sys.stderr.write(
                    f"--> FOAM FATAL ERROR: injected failure of participant {self.name} "
                    f"at time window {window}\n"
                )
                sys.stderr.flush()
                os._exit(self.exit_code)
            os.kill(os.getpid(), signal.SIGKILL)

    def at_end(self) -> int:
        if self.exit_code is not None and self.crash_at is None:
            sys.stderr.write(f"[{self.name}] injected error at the end of the run\n")
            return self.exit_code
        return 0


def run(args: argparse.Namespace) -> int:
    """Run one participant to the end of the coupling; returns the exit status."""
    name = args.participant
    faults = _Faults(args, name)
    cfg = load_precice_config(args.config)
    spec = cfg.participant(name)
    flow = load_flow(args.flow)(cfg, name, _options(args.option))
    precice = importlib.import_module(args.library)
    drawn = requested_fields()
    unknown = [field for field in drawn if field not in flow.field_names()]
    if unknown:
        sys.stderr.write(
            f"[{name}] ERROR: field(s) {unknown} requested for rendering, but flow "
            f"{type(flow).__name__} writes {list(flow.field_names())}; fix the env's "
            "render_fields\n"
        )
        return 2
    faults.check(0)
    participant = precice.Participant(name, str(args.config), 0, 1)
    ids: dict[str, np.ndarray] = {}
    for mesh in spec.provided_meshes:
        ids[mesh] = participant.set_mesh_vertices(mesh, flow.mesh_coordinates(mesh))
    for mesh in spec.api_access_meshes:
        participant.set_mesh_access_region(mesh, flow.access_region(mesh))
    if participant.requires_initial_data():
        for data, mesh in spec.write_data:
            if mesh in ids:
                participant.write_data(mesh, data, ids[mesh], flow.output(data, mesh))
    _write_fields(flow, drawn, 0.0)
    participant.initialize()
    for mesh in spec.api_access_meshes:
        mesh_ids, coords = participant.get_mesh_vertex_ids_and_coordinates(mesh)
        ids[mesh] = mesh_ids
        flow.register_mesh(mesh, coords)
    out_dir = Path(args.write_outputs) if args.write_outputs else None
    every_step = out_dir is not None and args.write_every_step
    t, window, iterations = 0.0, 0, 0
    saved: tuple[Any, float] | None = None
    print(f"[{name}] initialized, flow {type(flow).__name__}", flush=True)
    while participant.is_coupling_ongoing():
        if participant.requires_writing_checkpoint():
            saved = (flow.checkpoint(), t)
        dt = window_left = participant.get_max_time_step_size()
        if args.dt:
            dt = min(args.dt, dt)
        inputs = {
            (data, mesh): participant.read_data(mesh, data, ids[mesh], dt)
            for data, mesh in spec.read_data
            if mesh in ids
        }
        flow.step(t, dt, inputs)
        for data, mesh in spec.write_data:
            if mesh in ids:
                participant.write_data(mesh, data, ids[mesh], flow.output(data, mesh))
        if args.step_sleep:
            time.sleep(args.step_sleep)
        if every_step:
            assert out_dir is not None
            flow.write_outputs(out_dir, t + dt)
        if drawn and dt >= window_left - 1e-9 * max(window_left, 1.0):
            _write_fields(flow, drawn, t + dt)  # the window's last step: a frame's state
        participant.advance(dt)
        iterations += 1
        if participant.requires_reading_checkpoint():
            assert saved is not None
            flow.restore(saved[0])
            t = saved[1]
            continue
        t += dt
        if participant.is_time_window_complete():
            window += 1
            fields = " ".join(f"{k}={v:.6g}" for k, v in flow.summary().items())
            print(f"[{name}] window {window} t={t:.10g} steps={iterations} {fields}", flush=True)
            if out_dir is not None and not every_step:
                flow.write_outputs(out_dir, t)
            faults.check(window)
    participant.finalize()
    print(f"[{name}] finished after {window} windows, t={t:.10g}", flush=True)
    return faults.at_end()


def _write_fields(flow: Any, names: list[str], t: float) -> None:
    for field_name in names:
        field = flow.field(field_name, t)
        if field is not None:
            write_field_file(".", field)


def main(argv: Sequence[str] | None = None) -> int:
    return run(_parse(argv))


if __name__ == "__main__":
    sys.exit(main())
