"""The coupled run behind one Adapter: its index, run directory, solvers and session.

Across the episodes of one env this holds what outlives a reset: the env index (claimed
under the run root when none was given), the run directory with each solver's prepared
case, and the readers of solver outputs handed out by ``open_output``. Within an episode it
holds the :class:`~gymprecice.coupling.CouplingSession`: the coupling worker and the
solver processes, started, advanced and ended here. It calls no method of the user's env;
:mod:`gymprecice.episode` does.
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from gymprecice.env import lifecycle
from gymprecice.env.config import GymPreciceConfig
from gymprecice.env.coupling import CouplingSession, CouplingState, WorkerProcess
from gymprecice.env.pidregistry import PidRegistry, kill_recorded_groups
from gymprecice.env.rundir import (
    EnvIndexClaim,
    RunDirectory,
    claim_env_index,
    create_run_directory,
    env_root,
)
from gymprecice.env.solver_process import SolverProcess
from gymprecice.env.timed_reader import TimedReader
from gymprecice.plugin.errors import ConfigError
from gymprecice.plugin.manager import get_plugin_manager
from gymprecice.plugin.solver import LIBRARY_ENV_VAR, OutputReader, SolverContext

__all__ = ["CoupledRun"]

log = logging.getLogger("gymprecice.core")


class CoupledRun:
    """One env's run directory, solvers and coupling session (see the module docstring).

    ``idx`` is the env's index; without one, the lowest index that no live env under the
    same run root holds is claimed (a lock held until :meth:`release_claim`).
    """

    def __init__(
        self, config: GymPreciceConfig, idx: int | None, run_root: str | Path | None
    ) -> None:
        self.config = config
        self.run_root = run_root
        #: held while this env owns an index it was not given
        self.claim: EnvIndexClaim | None = None
        self.index_given = idx is not None
        self.env_index = idx if idx is not None else self._claim_index()
        self.hook = get_plugin_manager().hook
        self.timeouts = config.model.timeouts
        self.directory: RunDirectory | None = None
        #: every solver's context, by solver name (filled by :meth:`prepare`)
        self.solvers: dict[str, SolverContext] = {}
        #: the running episode's session; ``None`` between episodes
        self.session: CouplingSession | None = None
        self._readers: dict[tuple[str, str, str], OutputReader] = {}
        #: seconds the readers spent waiting for solver output in the current step
        self.output_wait = [0.0]

    # -- the env index ---------------------------------------------------------------------
    def _runs_base(self) -> Path:
        return env_root(self.config, 0, self.run_root).parent

    def _claim_index(self) -> int:
        """The lowest env index under the run root that no live env holds.

        Envs made without ``idx`` (``gym.make_vec`` in sync mode gives none) would
        otherwise all run in ``env_0`` and break each other's coupling. The claim is a
        lock file held until the env is closed, so it also holds across processes.
        """
        self.claim = claim_env_index(self._runs_base())
        return self.claim.index

    def reclaim(self) -> None:
        """Claim this env's index again (a reset after close), unless it was given."""
        if not self.index_given and self.claim is None:
            self.claim = claim_env_index(self._runs_base(), prefer=self.env_index)

    def release_claim(self) -> None:
        if self.claim is not None:
            self.claim.release()
            self.claim = None

    # -- directories and solvers -----------------------------------------------------------
    @property
    def env_dir(self) -> Path:
        """Where the run directory is (or will be), without preparing anything."""
        if self.directory is not None:
            return self.directory.root
        return env_root(self.config, self.env_index, self.run_root)

    def prepare(self) -> RunDirectory:
        """Make the run directory and prepare every solver's case (once)."""
        if self.directory is not None:
            return self.directory
        self.directory = create_run_directory(self.config, self.env_index, self.run_root)
        for spec in self.config.solvers.values():
            ctx = SolverContext(
                name=spec.name,
                kind=spec.kind,
                run_dir=self.directory.solver_dir(spec.path),
                source_dir=self.config.case_dir / spec.path,
                env_dir=self.directory.root,
                env_index=self.env_index,
                participant=spec.participant,
                options=dict(spec.options),
                config_file=self.config.file,
                precice=self.config.precice,
                precice_config_file=self.directory.precice_config_file,
                precice_library=self.config.precice_library,
            )
            lifecycle.prepare_case(self.hook, ctx)
            self.solvers[spec.name] = ctx
        return self.directory

    # -- solver outputs --------------------------------------------------------------------
    def open_output(self, solver: str, name: str, options: dict[str, Any]) -> OutputReader:
        """The reader of ``name`` of ``solver``: the same one until :meth:`close_readers`."""
        key = (solver, name, repr(sorted(options.items())))
        if key in self._readers:
            return self._readers[key]
        self.prepare()
        if solver not in self.solvers:
            raise ConfigError(f"no solver {solver!r}; the solvers are {sorted(self.solvers)}")
        reader = self.hook.gymprecice_open_output(
            solver=self.solvers[solver], name=name, options=options
        )
        if reader is None:
            raise ConfigError(
                f"no installed plugin opens output {name!r} of solver {solver!r} "
                f"(kind {self.solvers[solver].kind!r})"
            )
        timed = TimedReader(reader, self.output_wait, self.solvers_alive)
        self._readers[key] = timed
        return timed

    def close_readers(self) -> None:
        readers, self._readers = list(self._readers.values()), {}
        for reader in readers:
            try:
                reader.close()
            except Exception:
                pass

    # -- the session of an episode ---------------------------------------------------------
    def open_session(
        self,
        health_check: Callable[[SolverProcess], str | None],
        watch: Callable[[SolverProcess], str | None],
    ) -> tuple[CouplingSession, PidRegistry]:
        """A new session (its coupling worker started, no solver yet), now :attr:`session`."""
        directory = self.prepare()
        registry = PidRegistry(directory.root)
        worker = WorkerProcess(
            directory.state_dir / "coupling-worker.log",
            registry,
            io_timeout=self.timeouts.progress,
        )
        session = CouplingSession(
            worker,
            [],
            env_index=self.env_index,
            progress_timeout=self.timeouts.progress,
            kill_grace=self.timeouts.kill_grace,
            health_check=health_check,
            watch=watch,
        )
        self.session = session
        return session, registry

    def launch(
        self,
        session: CouplingSession,
        registry: PidRegistry,
        *,
        seed: int,
        options: Mapping[str, Any] | None,
        fields: Mapping[str, tuple[str, ...]],
        field_interval: float | None,
    ) -> None:
        """Reset every solver's case for this episode, then start every solver."""
        for ctx in self.solvers.values():
            ctx.rng = np.random.default_rng(seed)
            ctx.reset_options = dict(options or {})
            ctx.fields = fields.get(ctx.name, ())
            ctx.field_interval = field_interval if ctx.fields else None
            lifecycle.reset_case(self.hook, ctx)
        for ctx in self.solvers.values():
            spec = lifecycle.launch_spec(self.hook, ctx)
            # The solver's own preCICE bindings must be the env's (a Python solver reads
            # this); a plugin that sets the variable itself keeps its value.
            spec = dataclasses.replace(
                spec, env={LIBRARY_ENV_VAR: ctx.precice_library, **dict(spec.env)}
            )
            session.solvers.append(
                SolverProcess.start(ctx.name, spec, env_index=self.env_index, registry=registry)
            )

    def initialize(
        self,
        session: CouplingSession,
        meshes: Mapping[str, Any],
        direct: Mapping[str, list[float]],
        initial: dict[tuple[str, str], np.ndarray],
    ) -> CouplingState:
        """Initialize the coupling: the controller's meshes, its first data written."""
        assert self.directory is not None
        request = {
            "cwd": str(self.directory.root),
            "library": self.config.precice_library,
            "participant": self.config.participant,
            "config_file": str(self.directory.precice_config_file),
            "meshes": dict(meshes),
            "direct": dict(direct),
            "read": [
                (spec.mesh, data) for spec in self.config.interfaces.values() for data in spec.read
            ],
            "initial_data": initial,
        }
        return session.initialize(request, self.timeouts.reset)

    def advance(
        self, session: CouplingSession, writes: list[dict[tuple[str, str], np.ndarray]]
    ) -> CouplingState:
        """One env step: every window's data written, the coupling advanced through them."""
        return session.advance(writes, self.timeouts.step)

    def end(self, *, abort: bool) -> None:
        """Kill (or finish) the running session; it stays reachable until it is dead.

        A signal handler that closes the env during the kill grace must still find the
        session, and an exception out of the finish (a user handler raising
        ``SystemExit``) must not drop it alive.
        """
        session = self.session
        if session is None:
            return
        try:
            if abort:
                session.kill()
            else:
                session.finish(self.timeouts.finalize)
        except BaseException:
            session.kill()
            raise
        finally:
            if self.session is session:
                self.session = None

    def solvers_alive(self) -> None:
        """Raise the session's error if a solver has died (see :class:`TimedReader`)."""
        if self.session is not None and not self.session.closed:
            self.session.ensure_solvers_running("output")

    def kill_recorded(self) -> None:
        """Kill what this env's pid registry still records (normally nothing)."""
        if self.directory is None:
            return
        try:
            kill_recorded_groups(self.directory.root, grace=self.timeouts.kill_grace)
        except OSError as exc:
            log.debug("env %d: could not read its pid registry: %s", self.env_index, exc)
