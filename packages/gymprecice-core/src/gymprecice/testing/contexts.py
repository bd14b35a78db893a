"""Solver contexts as core builds them, for a plugin's own tests.

Core hands a plugin a :class:`~gymprecice.solver.SolverContext` at two moments, with
different paths (see docs/writing-a-plugin.md):

* **validation** (``gymprecice_validate_case``, when a configuration is loaded): the
  pristine case, ``run_dir == source_dir``, ``env_dir`` the case directory, and
  ``precice_config_file`` the case's own preCICE configuration;
* **run time** (every other per-solver hook): the env's real copy of the case under
  ``<run_root>/env_<i>/``, and ``precice_config_file`` the env's copy of the preCICE
  configuration (its exchange directory rewritten to the env's own).

:func:`make_solver_context` builds the run-time one (copying the case, as core does) and
:func:`validation_context` turns it into the validation one. Imports nothing heavy: usable
without pytest.
"""

from __future__ import annotations

import dataclasses
import shutil
from pathlib import Path
from typing import Any

import numpy as np

from gymprecice.plugin.solver import SolverContext

__all__ = ["make_solver_context", "validation_context"]


def make_solver_context(
    kind: str,
    source_dir: Path,
    base: Path,
    *,
    name: str = "solver",
    options: dict[str, Any] | None = None,
    participant: str | None = None,
    env_index: int = 0,
    seed: int = 0,
    precice_config: Path | None = None,
    config_file: Path | None = None,
    precice_library: str = "precice",
    reset_options: dict[str, Any] | None = None,
    state: dict[str, Any] | None = None,
) -> SolverContext:
    """Copy ``source_dir`` into ``base/env_<index>/<name>`` and describe it as core would.

    The copy is real (no symlinks into the pristine case), like each env's run directory.
    ``precice_config`` (a preCICE XML file) is copied into the env directory, as core copies
    it, and parsed: the context's ``precice`` and ``precice_config_file`` then hold what a
    hook sees in an env. ``config_file`` stands for the ``gymprecice-config.json`` that
    error messages name; ``precice_library`` is the module the env couples through (real
    pyprecice by default, as in core; :data:`~gymprecice.solver.TEST_DOUBLE_LIBRARY` for the
    test double); ``seed`` seeds ``rng``.
    """
    source_dir = Path(source_dir)
    env_dir = Path(base) / f"env_{env_index}"
    run_dir = env_dir / name
    shutil.copytree(source_dir, run_dir, symlinks=True)
    precice = precice_file = None
    if precice_config is not None:
        from gymprecice.plugin.precice_xml import load_precice_config

        precice_file = env_dir / Path(precice_config).name
        if not precice_file.exists():
            shutil.copyfile(precice_config, precice_file)
        precice = load_precice_config(precice_file)
    return SolverContext(
        name=name,
        kind=kind,
        run_dir=run_dir,
        source_dir=source_dir,
        env_dir=env_dir,
        env_index=env_index,
        participant=participant,
        options=dict(options or {}),
        config_file=Path(config_file) if config_file is not None else None,
        precice=precice,
        precice_config_file=precice_file,
        rng=np.random.default_rng(seed),
        reset_options=dict(reset_options or {}),
        state=dict(state or {}),
        precice_library=precice_library,
    )


def validation_context(solver: SolverContext, precice_config: Path | None = None) -> SolverContext:
    """The context ``gymprecice_validate_case`` gets for the same solver: the pristine case.

    ``run_dir`` and ``source_dir`` are both the pristine case, ``env_dir`` the directory
    holding it, and no run-time state (no ``rng``, empty ``state``). ``precice_config``
    (default: the run-time context's) is the pristine preCICE file, parsed.
    """
    precice, precice_file = solver.precice, solver.precice_config_file
    if precice_config is not None:
        from gymprecice.plugin.precice_xml import load_precice_config

        precice_file = Path(precice_config)
        precice = load_precice_config(precice_file)
    case_dir = solver.source_dir
    try:  # the run directory sits in the env directory as the solver sits in the case
        depth = len(solver.run_dir.relative_to(solver.env_dir).parts)
    except ValueError:
        depth = 1
    for _ in range(depth):
        case_dir = case_dir.parent
    return dataclasses.replace(
        solver,
        run_dir=solver.source_dir,
        env_dir=case_dir,
        precice=precice,
        precice_config_file=precice_file,
        rng=None,
        reset_options={},
        state={},
    )
