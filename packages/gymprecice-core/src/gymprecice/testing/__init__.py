"""Test tools for gymprecice and its plugins: a preCICE double, a scripted partner, cases.

Real preCICE is rarely installed where tests run, and real solvers are slow. These tools
let every test couple real processes anyway:

* :mod:`gymprecice.testing.fake_precice` - a drop-in for ``import precice`` (pyprecice v3):
  same API, same protocol checks and messages, same failure mode (a participant whose
  partner died blocks instead of raising; after ``PARTNER_LOSS`` seconds, 5, it gives up
  with preCICE's error, so that no solver outlives its controller). Select it with
  ``"precice": {"library": "gymprecice.testing.fake_precice"}`` in gymprecice-config.json
  or ``GYMPRECICE_PRECICE_LIBRARY=gymprecice.testing.fake_precice``. Every participant of a
  run must use the same library: core exports the env's as ``GYMPRECICE_PRECICE_LIBRARY`` to
  every solver it launches (``SolverContext.precice_library`` tells the plugin), and reports
  at reset a solver whose log shows the other one. Where real preCICE kills the process on a misuse (abort or
  segmentation fault), the double raises ``PreciceError`` unless
  ``GYMPRECICE_FAKE_PRECICE_MISUSE=crash`` asks it to die the same way.
  ``tests/test_real_precice.py`` runs the same scenarios against both libraries.
* :mod:`gymprecice.testing.partner` - ``python -m gymprecice.testing.partner --config ...
  --participant Fluid``: a solver participant whose physics comes from
  :mod:`gymprecice.testing.flows`, with fault injection (``--crash-at-window N``,
  ``--hang-at-window N``, ``--exit-code C``, ``--step-sleep S``), one stdout line per time
  window, and OpenFOAM-like output files (``--write-outputs DIR``). ``--library precice``
  runs it against real preCICE.
* ready cases under :data:`CASES_DIR`:

  ``fake_cylinder/precice-config.xml``
      Controller + Fluid, 2-D, parallel-explicit, window 0.01, max-time 1.0. The
      Controller provides ``Controller-Mesh-jet1``/``-jet2`` (writes ``Velocity``) and
      reads ``Pressure`` directly on the received ``Fluid-Mesh-cylinder``
      (``api-access``: call ``set_mesh_access_region`` before ``initialize``). Run the
      Fluid with the default flow (``CylinderFlow``); put the Controller's vertices at
      :func:`gymprecice.testing.flows.fake_cylinder_geometry` (any points work: the Fluid
      maps nearest-neighbour).
  ``fake_cylinder/precice-config-implicit.xml``
      the same, parallel-implicit (max-time 0.2, at most 5 iterations, relative
      convergence of ``Pressure``): the Controller must honour checkpoints.
  ``fake_flap/precice-config.xml``
      FSI as in the Gym-preCICE paper: Controller (``JetController`` flow, writes
      ``Velocity`` on ``Controller-Mesh``, reads ``Force``), Fluid (``FlapFluid``),
      Solid (``FlapSolid``, watch point ``Flap-Tip``), one ``multi`` scheme controlled by
      Fluid (max-time 0.2).
  ``fake_flap/precice-config-compositional.xml``
      the same participants; Controller-Fluid parallel-explicit, Fluid-Solid
      serial-implicit (the Controller never iterates).

  All use ``exchange-directory=""`` (the working directory); :func:`case_config` copies one
  with another exchange directory or end time.

A solver of kind ``command`` runs a partner with the argv from :func:`partner_command`
(set ``GYMPRECICE_DISABLE_PLUGINS=1`` in its environment to skip the plugin scan that
``import gymprecice`` does, which is most of a partner's start-up time)::

    argv = partner_command(config, "Fluid", crash_at_window=3, write_outputs=".")
    # [sys.executable, "-m", "gymprecice.testing.partner", "--config", ..., ...]

:func:`make_solver_context` builds the :class:`~gymprecice.solver.SolverContext` core would
hand a plugin's hooks in an env (:func:`validation_context`: the one validation gets), for a
plugin's own tests; :mod:`gymprecice.testing.conformance` is the suite every plugin runs.

This package's ``__init__`` stays import-light: ``python -m gymprecice.testing.partner``
passes through it.
"""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Any

__all__ = [
    "CASES_DIR",
    "case_config",
    "make_solver_context",
    "partner_command",
    "validation_context",
]


def __getattr__(name: str) -> Any:
    """``make_solver_context`` and ``validation_context``, imported on first use."""
    if name in ("make_solver_context", "validation_context"):
        from gymprecice.testing import contexts

        return getattr(contexts, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


#: The ready preCICE configurations (package data).
CASES_DIR = Path(__file__).resolve().parent / "cases"


def case_config(
    name: str,
    destination: str | os.PathLike[str],
    *,
    variant: str | None = None,
    max_time: float | None = None,
    exchange_directory: str | os.PathLike[str] | None = None,
) -> Path:
    """Copy ``cases/<name>/precice-config[-<variant>].xml`` into ``destination``.

    ``max_time`` replaces every ``<max-time value=...>``; ``exchange_directory`` every
    m2n's ``exchange-directory`` (made absolute, so participants with different working
    directories still meet). Returns the path of the copy, ``destination/precice-config.xml``.
    """
    filename = "precice-config.xml" if variant is None else f"precice-config-{variant}.xml"
    source = CASES_DIR / name / filename
    if not source.is_file():
        known = sorted(p.relative_to(CASES_DIR).as_posix() for p in CASES_DIR.rglob("*.xml"))
        raise FileNotFoundError(f"no test case {name}/{filename}; the cases are {known}")
    text = source.read_text()
    if max_time is not None:
        text = re.sub(r'(<max-time\s+value=")[^"]*(")', rf"\g<1>{max_time!r}\g<2>", text)
    if exchange_directory is not None:
        directory = Path(exchange_directory).resolve()
        text = re.sub(r'(exchange-directory=")[^"]*(")', rf"\g<1>{directory}\g<2>", text)
    target_dir = Path(destination)
    target_dir.mkdir(parents=True, exist_ok=True)
    target = target_dir / "precice-config.xml"
    target.write_text(text)
    return target


def partner_command(config: str | os.PathLike[str], participant: str, **kwargs: Any) -> list[str]:
    """Argv of ``python -m gymprecice.testing.partner`` (see :func:`partner.command`)."""
    from gymprecice.testing.partner import command

    return command(config, participant, **kwargs)
