"""Fields of a FEniCS participant for ``env.render()``: written by the script itself.

A FEniCS script runs in its own interpreter (Debian's dolfin, numpy 1.x), which cannot
import gymprecice, so it hands its fields over through files, by core's convention
(:mod:`gymprecice.fields`): when the env renders, launch sets

* ``GYMPRECICE_FIELDS``: the field names to write, comma-separated (e.g. ``T``);
* ``GYMPRECICE_FIELD_INTERVAL``: the coupling time in seconds between two frames (one
  action),

and the script writes ``gymprecice-fields/<name>.npz`` in its working directory at the
start and whenever its time reaches a multiple of the interval, replacing the previous
one: a ``numpy.savez`` of ``time`` (s), ``points`` (``(n, 2)``, e.g.
``mesh.coordinates()``), ``values`` (``(n,)``, e.g. ``u.compute_vertex_values(mesh)``),
``triangles`` (``(m, 3)``, ``mesh.cells()``) and ``label``, written to a temporary name
and renamed (``os.replace``) so the env never reads half a file. Without the variables
the script writes nothing, so an env that does not render costs nothing. The heated
plate's ``solid.py`` is the example. A script asked for a field it does not compute should
say so and exit: the reset then fails with its message.

Reset removes the folder, so a frame never shows the previous episode.
"""

from __future__ import annotations

import shutil
import zipfile
from pathlib import Path

from gymprecice.plugin import (
    FIELDS_DIR,
    FIELDS_ENV_VAR,
    ConfigError,
    Field,
    SolverContext,
    field_file,
    read_field_file,
)

__all__ = ["FIELD_INTERVAL_ENV_VAR", "clear_fields", "field_env", "read_field"]

#: Environment variable: the coupling time (s) between two frames, when the env renders.
FIELD_INTERVAL_ENV_VAR = "GYMPRECICE_FIELD_INTERVAL"


def field_env(solver: SolverContext) -> dict[str, str]:
    """What the script's environment says about rendering (``{}``: write nothing)."""
    if not solver.fields:
        return {}
    env = {FIELDS_ENV_VAR: ",".join(solver.fields)}
    if solver.field_interval:
        env[FIELD_INTERVAL_ENV_VAR] = repr(float(solver.field_interval))
    return env


def clear_fields(run_dir: Path) -> None:
    """Remove the previous episode's field files."""
    shutil.rmtree(run_dir / FIELDS_DIR, ignore_errors=True)


def read_field(solver: SolverContext, name: str, time: float) -> Field | None:
    """The script's latest ``gymprecice-fields/<name>.npz`` (``None`` until it exists)."""
    if name not in solver.fields:
        raise ConfigError(
            f"{solver.describe()}: field {name!r} was not requested from the script at reset "
            f"(it writes {list(solver.fields)}); add it to the env's render_fields"
        )
    path = field_file(solver.run_dir, name)
    try:
        return read_field_file(path, name)
    except FileNotFoundError:
        return None
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as exc:
        raise ConfigError(
            f"{solver.describe()}: {path} is not a field file as gymprecice reads it ({exc}); "
            "the script must numpy.savez time, points, values (and triangles, label) to a "
            "temporary name and os.replace it (see gymprecice_fenics.fields)"
        ) from None
