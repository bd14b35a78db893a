"""The Adapter: a Gymnasium environment whose physics is a preCICE-coupled simulation.

A user writes an environment by subclassing :class:`Adapter`, setting ``action_space`` and
``observation_space``, and overriding four methods (the Gym-preCICE paper's API):

* ``_get_action(action, write_var_list)``: turn an action into data for each interface;
* ``_get_observation(read_data, read_var_list)``: turn coupling data and/or solver outputs
  into an observation;
* ``_get_reward()``: the reward of the step that just ended;
* ``_close_external_resources()``: release what the env itself opened.

Everything generic is done here: configuration, the env's run directory, preparing,
resetting and launching solvers through plugins, the preCICE participant (in a watched
worker process), time windows and the smoothing of actions across them, seeding, and
clean teardown. Reaching the coupling's end time truncates the episode (a time limit, not
a terminal state). A solver that diverges under the agent's actions terminates it, with
the env's ``divergence_penalty`` as reward and ``info["diverged"]`` (see
:mod:`gymprecice.divergence`); a non-finite observation or reward from the user's methods
is refused with the method's name and the step, never handed to the learner.
"""

from __future__ import annotations

import atexit
import dataclasses
import logging
import math
import os
import signal
import threading
import time
import weakref
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, NamedTuple

import gymnasium as gym
import numpy as np

from gymprecice import lifecycle
from gymprecice.actions import ActionSchedule
from gymprecice.config import (
    GymPreciceConfig,
    InterfaceSpec,
    check_solver_kinds,
    load_config,
)
from gymprecice.coupling import CouplingSession, CouplingState, WorkerProcess
from gymprecice.divergence import HARD_FAULT_STATUSES, Divergence, checked_penalty
from gymprecice.errors import (
    ConfigError,
    CouplingError,
    SolverDivergedError,
    SolverError,
    SolverTimeoutError,
)
from gymprecice.pidregistry import kill_recorded_groups
from gymprecice.plugins import get_plugin_manager, plugin_failures, solver_kinds
from gymprecice.precice_library import mixed_library_problem
from gymprecice.processes import PidRegistry, SolverProcess
from gymprecice.rundir import (
    EnvIndexClaim,
    RunDirectory,
    claim_env_index,
    create_run_directory,
    env_root,
)
from gymprecice.solver import LIBRARY_ENV_VAR, InterfaceGeometry, OutputReader, SolverContext

__all__ = ["Adapter", "DataDict", "DataRef", "Timing"]

#: seconds between two looks at the solvers while an env waits for a solver's output file
OUTPUT_WAIT_SLICE_S = 0.5

log = logging.getLogger(__name__)


class DataRef(NamedTuple):
    """One piece of coupling data: ``data`` on the controller mesh of ``interface``.

    ``str(ref)`` is ``"<data>-<interface>"``, the key the Gym-preCICE paper used.
    """

    interface: str
    mesh: str
    data: str

    def __str__(self) -> str:
        return f"{self.data}-{self.interface}"


class DataDict(dict):
    """Coupling data keyed by :class:`DataRef`, also reachable by ``"Data-interface"``.

    An interface with a single data field can be looked up by its interface name too.
    """

    def __getitem__(self, key: Any) -> Any:
        if isinstance(key, DataRef) or not isinstance(key, str):
            return super().__getitem__(key)
        for ref in self:
            if str(ref) == key:
                return super().__getitem__(ref)
        matches = [ref for ref in self if ref.interface == key]
        if len(matches) == 1:
            return super().__getitem__(matches[0])
        raise KeyError(key)


class Timing(Mapping[str, float]):
    """Seconds spent in one step or reset: ``precice_s``, ``wait_s``, ``env_s``, ``step_s``.

    ``wait_s`` is the time spent waiting for the solvers: in preCICE, in the
    ``wait_until`` of readers from :meth:`Adapter.open_output`, and on an episode's last
    step in finalizing and letting the solvers exit; ``env_s`` the rest of the env's own
    code, so ``wait_s + env_s`` accounts for ``step_s`` but for a few bookkeeping lines. Read it like a dict. Two timings compare equal when they measure the same things:
    wall-clock figures describe the machine, not the environment's state, so Gymnasium's
    determinism check (which compares the infos of two identical steps) must not see them.
    """

    __slots__ = ("_seconds",)

    def __init__(self, seconds: Mapping[str, float]) -> None:
        self._seconds = dict(seconds)

    def __getitem__(self, key: str) -> float:
        return self._seconds[key]

    def __iter__(self):
        return iter(self._seconds)

    def __len__(self) -> int:
        return len(self._seconds)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Timing) and self._seconds.keys() == other._seconds.keys()

    __hash__ = None  # type: ignore[assignment]

    def __repr__(self) -> str:
        return f"Timing({self._seconds!r})"

    def __reduce__(self):
        return (Timing, (self._seconds,))


#: Envs with an episode possibly running, ended at interpreter exit (see Adapter.close).
_LIVE_ENVS: weakref.WeakSet[Adapter] = weakref.WeakSet()


@atexit.register
def _end_live_episodes() -> None:
    """A script that forgets ``env.close()`` (or dies on an exception) leaves no solver."""
    for env in list(_LIVE_ENVS):
        try:
            env.close()
        except Exception:
            pass


def _end_live_episodes_and_die(signum: int, frame: object) -> None:
    """SIGTERM/SIGHUP (a scheduler, ``timeout``, a closed terminal): clean up, then die.

    atexit does not run when a signal kills Python, which would leave the solvers waiting
    for a controller that is gone. The signal is re-raised with its default action, so
    the process still ends as the sender meant (exit status -signum).
    """
    _end_live_episodes()
    signal.signal(signum, signal.SIG_DFL)
    os.kill(os.getpid(), signum)


def _clean_up_on_termination_signals() -> None:
    """Install :func:`_end_live_episodes_and_die` where nobody else handles the signal.

    Only signals at their default action are taken (a learner's or a vector worker's own
    handler stays in charge), and only from the main thread, the one Python allows.
    """
    if threading.current_thread() is not threading.main_thread():
        return
    for signum in (signal.SIGTERM, signal.SIGHUP):
        if signal.getsignal(signum) is signal.SIG_DFL:
            signal.signal(signum, _end_live_episodes_and_die)


class _TimedReader:
    """A solver output reader whose ``wait_until`` calls are timed and watched.

    Waiting for a solver's output files is waiting for the solver, as much as waiting in
    preCICE is; timing it lets ``info["timing"]`` count it as such instead of as env code
    (an env that waits for a watch point would otherwise look 98 % busy in Python).
    It is also watched like a wait in preCICE: the wait runs in slices of
    :data:`OUTPUT_WAIT_SLICE_S`, and between two slices ``alive()`` raises if a solver has
    died, so a crashed or diverged solver ends the step at once instead of after the
    reader's whole timeout. Everything else goes straight to the plugin's reader.
    """

    def __init__(
        self, reader: OutputReader, clock: list[float], alive: Callable[[], None] | None = None
    ) -> None:
        self._reader = reader
        self._clock = clock
        self._alive = alive

    def wait_until(self, time_: float, timeout: float, *args: Any, **kwargs: Any) -> Any:
        wait = getattr(self._reader, "wait_until", None)
        if wait is None:
            raise AttributeError(
                f"{type(self._reader).__name__} has no wait_until: the plugin's reader does not "
                "follow gymprecice.solver.WaitableOutputReader; poll read_new() instead"
            )
        started = time.perf_counter()
        try:
            if self._alive is None:
                return wait(time_, timeout, *args, **kwargs)
            deadline = time.monotonic() + max(0.0, timeout)
            while True:
                left = deadline - time.monotonic()
                try:
                    return wait(time_, min(left, OUTPUT_WAIT_SLICE_S), *args, **kwargs)
                except TimeoutError as exc:
                    if left <= OUTPUT_WAIT_SLICE_S:  # the reader's own error, its last slice
                        exc.add_note(f"(waited {timeout:g} s in all, every solver running)")
                        raise
                    self._alive()
        finally:
            self._clock[0] += time.perf_counter() - started

    def __getattr__(self, name: str) -> Any:
        if name in ("_reader", "_clock", "_alive"):  # not set yet (copy, unpickling)
            raise AttributeError(name)
        return getattr(self._reader, name)


class Adapter(gym.Env):
    """Base class of every gymprecice environment (see the module docstring)."""

    metadata: dict[str, Any] = {"render_modes": []}
    #: Reward of the step in which a solver diverged; the configuration's
    #: ``environment.divergence_penalty`` overrides it. Pick it on the scale of the task's
    #: rewards: low enough that diverging never pays better than controlling.
    divergence_penalty: float = -10.0

    def __init__(
        self,
        options: Mapping[str, Any] | str | Path | None = None,
        idx: int | None = None,
        *,
        run_root: str | Path | None = None,
        case_dir: str | Path | None = None,
    ) -> None:
        super().__init__()
        if options is None:
            raise ConfigError(
                "Adapter needs its configuration: a path to gymprecice-config.json (or the case "
                "directory holding it), or the parsed dict"
            )
        self.config: GymPreciceConfig = load_config(options, case_dir=case_dir)
        check_solver_kinds(self.config, solver_kinds(), plugin_failures())
        configured = self.config.model.environment.divergence_penalty
        self._divergence_penalty = checked_penalty(
            type(self).divergence_penalty if configured is None else configured,
            self.config.where() if configured is not None else type(self).__qualname__,
            "environment.divergence_penalty" if configured is not None else "divergence_penalty",
        )
        self._run_root = run_root
        #: held while this env owns an index it was not given (see _claim_index)
        self._claim: EnvIndexClaim | None = None
        self.env_index = idx if idx is not None else self._claim_index()
        self._hook = get_plugin_manager().hook
        model = self.config.model
        self._schedule = ActionSchedule(
            model.actions.scheme, model.actions.windows, model.actions.filter_alpha
        )
        self._timeouts = model.timeouts
        self._write_refs = [
            DataRef(i.name, i.mesh, d) for i in self.config.interfaces.values() for d in i.write
        ]
        self._read_refs = [
            DataRef(i.name, i.mesh, d) for i in self.config.interfaces.values() for d in i.read
        ]
        self._user_vertices: dict[str, np.ndarray] = {}
        self._direct_geometry: dict[str, InterfaceGeometry] = {}
        self._geometry: dict[str, InterfaceGeometry] | None = None
        self._run: RunDirectory | None = None
        self._solvers: dict[str, SolverContext] = {}
        self._session: CouplingSession | None = None
        self._readers: dict[tuple[str, str, str], OutputReader] = {}
        #: seconds the readers spent waiting for solver output in the current step
        self._output_wait = [0.0]
        self._episode_active = False
        self._episode_over = False
        self._closed = False
        self._index_given = idx is not None
        self._clipping_reported = False
        self.time = 0.0
        self.time_window = 0
        self.dt: float | None = self.config.time_window_size
        self.end_time: float | None = self.config.end_time
        self._last_read: DataDict = DataDict()
        #: the last observation handed out: what a diverged step returns
        self._last_obs: Any = None
        self._steps = 0

    # -- the user API ----------------------------------------------------------------------
    def _get_action(self, action: Any, write_var_list: list[DataRef]) -> Mapping[Any, Any]:
        """Map ``action`` to ``{DataRef (or its name): array}`` for every written data."""
        raise NotImplementedError

    def _get_observation(self, read_data: DataDict, read_var_list: list[DataRef]) -> Any:
        """Build the observation from coupling data and/or solver outputs."""
        raise NotImplementedError

    def _get_reward(self) -> float:
        """Reward of the step that just ended."""
        raise NotImplementedError

    def _close_external_resources(self) -> None:
        """Release files or handles the env itself opened (called at reset and close)."""

    def _get_terminated(self) -> bool:
        """Override when the task has a real terminal state (default: it has none)."""
        return False

    def _initial_action(self) -> np.ndarray:
        """Actuator state at the start of an episode (default: zeros of the action space)."""
        shape = getattr(self.action_space, "shape", None) or ()
        return np.zeros(shape, dtype=float)

    # -- geometry and directories ----------------------------------------------------------
    @property
    def env_dir(self) -> Path:
        """Where this env's run directory is (or will be), without preparing anything.

        A supervisor needs it before preparation starts, to find the pid registry of a
        preparation that hangs.
        """
        return (
            self._run.root
            if self._run is not None
            else env_root(self.config, self.env_index, self._run_root)
        )

    @property
    def run_dir(self) -> Path:
        """This env's run directory (made and prepared on first use)."""
        self._ensure_prepared()
        assert self._run is not None
        return self._run.root

    @property
    def solver_dirs(self) -> dict[str, Path]:
        self._ensure_prepared()
        return {name: ctx.run_dir for name, ctx in self._solvers.items()}

    @property
    def write_var_list(self) -> list[DataRef]:
        return list(self._write_refs)

    @property
    def read_var_list(self) -> list[DataRef]:
        return list(self._read_refs)

    def set_interface_vertices(self, interface: str, coordinates: Any) -> None:
        """Set the controller vertices of ``interface`` by hand (overrides plugins)."""
        if interface not in self.config.interfaces:
            raise ConfigError(
                f"{self.config.where()}: no interface {interface!r}; the interfaces are "
                f"{sorted(self.config.interfaces)}"
            )
        coords = np.atleast_2d(np.asarray(coordinates, dtype=float))
        dims = self.config.interfaces[interface].dimensions
        if coords.shape[1] != dims:
            raise ValueError(
                f"interface {interface!r}: coordinates have {coords.shape[1]} columns but mesh "
                f"{self.config.interfaces[interface].mesh!r} is {dims}-D"
            )
        self._user_vertices[interface] = coords
        self._geometry = None

    def _set_precice_vectices(self, coords: Mapping[str, Any]) -> None:
        """Gym-preCICE v0.1 spelling: ``{"write_to": {name: coords}, "read_from": {...}}``."""
        groups = coords.values() if {"write_to", "read_from"} & set(coords) else [coords]
        for group in groups:
            for name, value in group.items():
                self.set_interface_vertices(name, value)

    @property
    def interface_geometry(self) -> dict[str, InterfaceGeometry]:
        """Vertices (and normals/areas where a plugin knows them) of every interface."""
        if self._geometry is None:
            self._geometry = {
                name: self._find_geometry(spec)
                for name, spec in self.config.interfaces.items()
                if not spec.direct or name in self._direct_geometry or name in self._user_vertices
            }
        return self._geometry

    def _access_region(self, spec: InterfaceSpec) -> list[float]:
        """Bounding box of a direct-access mesh: the user's, or all of space."""
        region = self.config.controller.access_regions.get(spec.name)
        if region is not None:
            return list(region)
        return [-1e300, 1e300] * spec.dimensions

    def _find_geometry(self, spec: InterfaceSpec) -> InterfaceGeometry:
        if spec.name in self._user_vertices:
            return InterfaceGeometry(self._user_vertices[spec.name])
        if spec.direct:
            if spec.name in self._direct_geometry:
                return self._direct_geometry[spec.name]
            raise ConfigError(
                f"interface {spec.name!r} reads mesh {spec.mesh!r} through direct access: "
                f"its vertices are defined by {spec.partner!r} and known after reset()"
            )
        self._ensure_prepared()
        for solver in self._solvers.values():
            if spec.partner and solver.participant and solver.participant != spec.partner:
                continue
            geometry = self._hook.gymprecice_interface_geometry(
                solver=solver, interface=spec.name, mesh=spec.partner_mesh or spec.mesh
            )
            if geometry is not None:
                return _fit_dimensions(geometry, spec.dimensions)
        raise ConfigError(
            f"{self.config.where()}: no plugin knows the vertices of interface {spec.name!r} "
            f"(mesh {spec.mesh!r}, coupled to {spec.partner or 'no participant'}'s mesh "
            f"{spec.partner_mesh!r}); call self.set_interface_vertices({spec.name!r}, coords) "
            "in your env's __init__"
        )

    def open_output(self, solver: str, name: str, /, **options: Any) -> OutputReader:
        """An incremental reader of a solver output, e.g. ``open_output("fluid", "probes")``.

        The same arguments give the same reader until the episode ends, so an env can ask
        for it in every ``_get_observation`` and read only what is new; core closes every
        reader at reset and close.
        """
        key = (solver, name, repr(sorted(options.items())))
        if key in self._readers:
            return self._readers[key]
        self._ensure_prepared()
        if solver not in self._solvers:
            raise ConfigError(f"no solver {solver!r}; the solvers are {sorted(self._solvers)}")
        reader = self._hook.gymprecice_open_output(
            solver=self._solvers[solver], name=name, options=options
        )
        if reader is None:
            raise ConfigError(
                f"no installed plugin opens output {name!r} of solver {solver!r} "
                f"(kind {self._solvers[solver].kind!r})"
            )
        timed = _TimedReader(reader, self._output_wait, self._solvers_alive)
        self._readers[key] = timed
        return timed

    def _ensure_prepared(self) -> None:
        if self._run is not None:
            return
        self._run = create_run_directory(self.config, self.env_index, self._run_root)
        for spec in self.config.solvers.values():
            ctx = SolverContext(
                name=spec.name,
                kind=spec.kind,
                run_dir=self._run.solver_dir(spec.path),
                source_dir=self.config.case_dir / spec.path,
                env_dir=self._run.root,
                env_index=self.env_index,
                participant=spec.participant,
                options=dict(spec.options),
                config_file=self.config.file,
                precice=self.config.precice,
                precice_config_file=self._run.precice_config_file,
                precice_library=self._library(),
            )
            lifecycle.prepare_case(self._hook, ctx)
            self._solvers[spec.name] = ctx

    # -- Gymnasium API ---------------------------------------------------------------------
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]:
        super().reset(seed=seed)
        started = time.perf_counter()
        self._end_episode(abort=True)
        self._close_readers()
        self._close_external_resources()
        if self._closed:  # reset() after close() reopens the env: close() works again
            self._closed = False
            if not self._index_given and self._claim is None:
                self._claim = claim_env_index(self._runs_base(), prefer=self.env_index)
        self._ensure_prepared()
        assert self._run is not None
        # From here on solvers may run: exit-time cleanup and SIGTERM/SIGHUP must find them,
        # including during this first reset.
        _LIVE_ENVS.add(self)
        _clean_up_on_termination_signals()
        registry = PidRegistry(self._run.root)
        worker = WorkerProcess(
            self._run.state_dir / "coupling-worker.log",
            registry,
            io_timeout=self._timeouts.progress,
        )
        session = CouplingSession(
            worker,
            [],
            env_index=self.env_index,
            progress_timeout=self._timeouts.progress,
            kill_grace=self._timeouts.kill_grace,
            health_check=self._health_check,
            watch=self._watch_solver,
        )
        self._session = session
        try:
            episode_seed = int(self.np_random.integers(2**63 - 1))
            for ctx in self._solvers.values():
                ctx.rng = np.random.default_rng(episode_seed)
                ctx.reset_options = dict(options or {})
                lifecycle.reset_case(self._hook, ctx)
            for ctx in self._solvers.values():
                spec = lifecycle.launch_spec(self._hook, ctx)
                # The solver's own preCICE bindings must be the env's (a Python solver reads
                # this); a plugin that sets the variable itself keeps its value.
                spec = dataclasses.replace(
                    spec, env={LIBRARY_ENV_VAR: ctx.precice_library, **dict(spec.env)}
                )
                session.solvers.append(
                    SolverProcess.start(ctx.name, spec, env_index=self.env_index, registry=registry)
                )
            self._schedule.start(self._initial_action())
            initial = self._collect_write(self._schedule.current)
            state = session.initialize(self._init_request(initial), self._timeouts.reset)
        except BaseException:
            self._end_episode(abort=True)
            raise
        self._episode_active = True
        self._episode_over = False
        self._apply(state)
        self._steps = 0
        obs = self._observed()
        info = self._info(state, {"reset_s": time.perf_counter() - started})
        return obs, info

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        if not self._episode_active or self._session is None:
            if self._episode_over:
                raise gym.error.ResetNeeded(
                    "the episode has ended (truncated or terminated); call reset() before step()"
                )
            raise gym.error.ResetNeeded("call reset() before step()")
        started = time.perf_counter()
        action = self._checked_action(action)
        windows = self._windows_left()
        writes = [self._collect_write(value) for value in self._schedule.spread(action, windows)]
        env_s = time.perf_counter() - started
        waited = time.perf_counter()
        session = self._session
        try:
            state = session.advance(writes, self._timeouts.step)
        except (SolverError, CouplingError) as exc:
            self._end_episode(abort=True)
            divergence = self._divergence(exc, session)
            if divergence is None:
                raise
            return self._diverged(divergence, started)
        except BaseException:
            # Ctrl-C, or SystemExit from the user's own signal handler: the episode cannot
            # go on, and nothing of it may outlive this env.
            self._end_episode(abort=True)
            raise
        evidence = self._watch_all(session)
        if evidence is not None:  # diverging, though the step itself completed
            self._end_episode(abort=True)
            return self._diverged(evidence, started)
        wait_s = time.perf_counter() - waited
        self._apply(state)
        self._steps += 1
        after = time.perf_counter()
        self._output_wait[0] = 0.0
        try:
            obs = self._observed()
            reward = self._rewarded()
        except (SolverError, CouplingError) as exc:  # a solver died while its output was awaited
            self._end_episode(abort=True)
            divergence = self._divergence(exc, session)
            if divergence is None:
                raise
            return self._diverged(divergence, started)
        except NonFiniteValueError:
            # NaN forces are what a diverging flow writes first; its log may lag behind
            # its output files (buffered), so give the plugins a moment to confirm.
            evidence = self._confirm_divergence(session)
            if evidence is None:
                self._end_episode(abort=True)
                raise
            self._end_episode(abort=True)
            return self._diverged(evidence, started)
        terminated = bool(self._get_terminated())
        truncated = not state.ongoing and not terminated
        output_wait = self._output_wait[0]
        wait_s += output_wait  # waiting for a solver's files is waiting for the solver
        env_s += time.perf_counter() - after - output_wait
        if terminated or truncated:
            # Finalizing and waiting for the solvers to exit is waiting for the solvers
            # (tens of ms on the last step); without this it would fall in no bucket.
            finishing = time.perf_counter()
            self._end_episode(abort=terminated and state.ongoing)
            wait_s += time.perf_counter() - finishing
            self._episode_over = True
        info = self._info(
            state,
            {
                "precice_s": state.precice_s,
                "wait_s": wait_s,
                "env_s": env_s,
                "step_s": time.perf_counter() - started,
            },
        )
        return obs, reward, terminated, truncated, info

    def close(self) -> None:
        """End everything this env started; safe to call any number of times.

        A call made while another one waits out the kill grace (a SIGTERM handler, a
        second Ctrl-C) does not return early: it kills what is left at once. Whatever the
        pid registry still records (a solver started an instant before an interrupt) is
        killed last. ``reset()`` after ``close()`` reopens the env.
        """
        if self._closed and self._session is None:
            return
        self._closed = True
        try:
            self._end_episode(abort=True)
            self._close_readers()
            self._close_external_resources()
        finally:
            self._kill_recorded()
            _LIVE_ENVS.discard(self)
            if self._claim is not None:
                self._claim.release()
                self._claim = None

    def __del__(self) -> None:
        try:
            if not getattr(self, "_closed", True):
                self._end_episode(abort=True)
            claim = getattr(self, "_claim", None)
            if claim is not None:
                claim.release()
        except Exception:
            pass

    # -- internals -------------------------------------------------------------------------
    def _library(self) -> str:
        return self.config.precice_library

    def _init_request(self, initial: dict[tuple[str, str], np.ndarray]) -> dict[str, Any]:
        assert self._run is not None
        interfaces = self.config.interfaces.values()
        meshes = {
            spec.mesh: self.interface_geometry[spec.name].coordinates
            for spec in interfaces
            if not spec.direct
        }
        direct = {spec.mesh: self._access_region(spec) for spec in interfaces if spec.direct}
        return {
            "cwd": str(self._run.root),
            "library": self._library(),
            "participant": self.config.participant,
            "config_file": str(self._run.precice_config_file),
            "meshes": meshes,
            "direct": direct,
            "read": [(ref.mesh, ref.data) for ref in self._read_refs],
            "initial_data": initial,
        }

    def _collect_write(self, value: Any) -> dict[tuple[str, str], np.ndarray]:
        if not self._write_refs:
            return {}
        produced = self._get_action(value, self.write_var_list)
        out: dict[tuple[str, str], np.ndarray] = {}
        for ref in self._write_refs:
            array = _lookup(produced, ref, self._write_refs)
            if array is None:
                raise KeyError(
                    f"_get_action returned no data for {ref} (interface {ref.interface!r}, data "
                    f"{ref.data!r}); return a dict keyed by the entries of write_var_list"
                )
            out[(ref.mesh, ref.data)] = self._shaped(ref, array)
        return out

    def _shaped(self, ref: DataRef, array: Any) -> np.ndarray:
        n = len(self.interface_geometry[ref.interface].coordinates)
        width = self.config.precice.data_dimension(ref.data, ref.mesh)
        values = np.asarray(array, dtype=float)
        expected = (n,) if width == 1 else (n, width)
        if values.shape != expected:
            try:
                values = values.reshape(expected)
            except ValueError:
                raise ValueError(
                    f"_get_action gave {ref} with shape {values.shape}; expected {expected} "
                    f"({n} vertices of interface {ref.interface!r}"
                    + (")" if width == 1 else f", {width}-D vector data)")
                ) from None
        return values

    def _apply(self, state: CouplingState) -> None:
        if state.coordinates:
            for spec in self.config.interfaces.values():
                if spec.mesh in state.coordinates:
                    coords = np.asarray(state.coordinates[spec.mesh])
                    self._direct_geometry[spec.name] = InterfaceGeometry(coords)
            self._geometry = None
        self.time = state.time
        self.time_window = state.windows
        if state.dt:
            self.dt = state.dt
        by_key = {(ref.mesh, ref.data): ref for ref in self._read_refs}
        self._last_read = DataDict({by_key[key]: value for key, value in state.read.items()})

    def _windows_left(self) -> int:
        """Windows the next step spans: all of them, or what is left until the end time.

        A last partial window counts as one (preCICE shortens it); a remainder below a
        millionth of a window is rounding noise in ``time``, not a window.
        """
        n = self._schedule.windows
        if self.end_time is None or not self.dt:
            return n
        left = math.ceil((self.end_time - self.time) / self.dt - 1e-6)
        return max(1, min(n, left))

    def _checked_action(self, action: Any) -> Any:
        """Refuse an action the action space cannot hold; clip one outside its bounds.

        A wrong shape would be spread and written as something else, and one NaN makes
        every later observation NaN, so both raise ``ValueError``. Values outside a Box's
        bounds are clipped to them, as Gymnasium's ``ClipAction`` does, and the first
        clipping of the env is logged.
        """
        space = self.action_space
        if not isinstance(space, gym.spaces.Box):
            return action
        try:
            values = np.asarray(action, dtype=float)
        except (TypeError, ValueError):
            raise ValueError(
                f"env {self.env_index}: the action {action!r} is not numeric; the action space "
                f"is {space}"
            ) from None
        if values.shape != space.shape:
            raise ValueError(
                f"env {self.env_index}: the action has shape {values.shape}, but the action "
                f"space {space} expects shape {space.shape}"
            )
        if not np.all(np.isfinite(values)):
            raise ValueError(
                f"env {self.env_index}: the action {values.tolist()} is not finite (NaN or "
                "infinity); check the policy's output"
            )
        clipped = np.clip(values, space.low, space.high)
        if np.array_equal(clipped, values):
            return action
        if not self._clipping_reported:
            self._clipping_reported = True
            log.warning(
                "env %d: action %s is outside the action space's bounds [%s, %s] and was "
                "clipped (reported once per env)",
                self.env_index,
                values.tolist(),
                space.low.tolist(),
                space.high.tolist(),
            )
        return clipped.astype(space.dtype)

    def _info(self, state: CouplingState, timing: dict[str, float]) -> dict[str, Any]:
        return {
            "time": state.time,
            "time_window": state.windows,
            "env_index": self.env_index,
            "timing": Timing(timing),
        }

    # -- divergence and guards ------------------------------------------------------------
    def _observed(self) -> Any:
        """The user's observation, refused if it holds NaN or infinity."""
        obs = self._get_observation(self._last_read, self.read_var_list)
        _refuse_non_finite(obs, "_get_observation", self.env_index, self._steps)
        self._last_obs = obs
        return obs

    def _rewarded(self) -> float:
        reward = float(self._get_reward())
        _refuse_non_finite(reward, "_get_reward", self.env_index, self._steps)
        return reward

    def _watch_solver(self, process: SolverProcess) -> str | None:
        """Divergence evidence from a running solver's log (the coupling's ``watch``)."""
        ctx = self._solvers.get(process.name)
        if ctx is None:
            return None
        return self._hook.gymprecice_detect_divergence(
            solver=ctx, log_text=process.log_tail(200), returncode=None
        )

    def _watch_all(self, session: Any) -> Divergence | None:
        for process in session.solvers:
            if process.poll() is None:
                evidence = self._watch_solver(process)
                if evidence:
                    return Divergence(process.name, self.time, evidence)
        return None

    def _confirm_divergence(self, session: Any, patience: float = 5.0) -> Divergence | None:
        """Watch the solvers' logs for up to ``patience`` s (bounded by the progress timeout)."""
        deadline = time.monotonic() + min(patience, self._timeouts.progress)
        while True:
            evidence = self._watch_all(session)
            if evidence is not None or time.monotonic() >= deadline:
                return evidence
            time.sleep(0.2)

    def _divergence(self, exc: Exception, session: Any) -> Divergence | None:
        """Whether a failed step is the solver's divergence rather than a fault.

        A hang stays a fault, and so does a culprit killed from outside or crashed by
        its binary (:data:`~gymprecice.divergence.HARD_FAULT_STATUSES`). Otherwise each
        solver's plugin classifies its exit and log, the failing solver first.
        """
        if isinstance(exc, SolverDivergedError):
            return Divergence(exc.solver or "solver", self.time, exc.evidence)
        if isinstance(exc, SolverTimeoutError) or session is None:
            return None
        culprit = getattr(exc, "solver", None)
        processes = sorted(session.solvers, key=lambda p: p.name != culprit)
        for process in processes:
            status = process.poll()
            if process.name == culprit and status in HARD_FAULT_STATUSES:
                return None
            ctx = self._solvers.get(process.name)
            if ctx is None or status is None:
                continue
            evidence = self._hook.gymprecice_detect_divergence(
                solver=ctx, log_text=process.log_tail(200), returncode=status
            )
            if evidence:
                return Divergence(process.name, self.time, evidence)
        return None

    def _diverged(
        self, divergence: Divergence, started: float
    ) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        """The terminal step of a diverged episode: last observation, the penalty."""
        self._episode_over = True
        log.info(
            "env %d: solver %r diverged at t=%g: %s",
            self.env_index,
            divergence.solver,
            divergence.time,
            divergence.evidence,
        )
        info = {
            "time": self.time,
            "time_window": self.time_window,
            "env_index": self.env_index,
            "diverged": divergence.as_info(),
            "timing": Timing({"step_s": time.perf_counter() - started}),
        }
        return self._last_obs, self._divergence_penalty, True, False, info

    def _solvers_alive(self) -> None:
        """Raise the session's error if a solver has died (see :class:`_TimedReader`)."""
        if self._session is not None and not self._session.closed:
            self._session.ensure_solvers_running("output")

    def _health_check(self, process: SolverProcess) -> str | None:
        """What is wrong with a waiting or exited solver: core's own check, then the plugin's.

        Core checks that the solver runs the env's preCICE library (a mixed set-up waits
        forever); the plugin's diagnosis comes without the solver's name.

        Core's error message names the solver and the env already; a plugin that starts
        its message with ``solver.describe()`` (as the hook spec once showed) would have
        it twice.
        """
        ctx = self._solvers.get(process.name)
        if ctx is None:
            return None
        log_text = process.log_tail(200)
        mixed = mixed_library_problem(ctx.precice_library, log_text)
        if mixed:
            return mixed
        problem = self._hook.gymprecice_check_solver(solver=ctx, log_text=log_text)
        return _without_label(problem, ctx.describe()) if problem else None

    def _end_episode(self, *, abort: bool) -> None:
        """Kill (or finish) the running session; it stays reachable until it is dead.

        A signal handler that calls :meth:`close` during the kill grace must still find
        the session, and an exception out of the finish (a user handler raising
        ``SystemExit``) must not drop it alive.
        """
        self._episode_active = False
        session = self._session
        if session is None:
            return
        try:
            if abort:
                session.kill()
            else:
                session.finish(self._timeouts.finalize)
        except BaseException:
            session.kill()
            raise
        finally:
            if self._session is session:
                self._session = None

    def _kill_recorded(self) -> None:
        """Kill what this env's pid registry still records (normally nothing)."""
        if self._run is None:
            return
        try:
            kill_recorded_groups(self._run.root, grace=self._timeouts.kill_grace)
        except OSError as exc:
            log.debug("env %d: could not read its pid registry: %s", self.env_index, exc)

    def _runs_base(self) -> Path:
        return env_root(self.config, 0, self._run_root).parent

    def _claim_index(self) -> int:
        """The lowest env index under the run root that no live env holds.

        Envs made without ``idx`` (``gym.make_vec`` in sync mode gives none) would
        otherwise all run in ``env_0`` and break each other's coupling. The claim is a
        lock file held until :meth:`close`, so it also holds across processes.
        """
        self._claim = claim_env_index(self._runs_base())
        return self._claim.index

    def _close_readers(self) -> None:
        readers, self._readers = list(self._readers.values()), {}
        for reader in readers:
            try:
                reader.close()
            except Exception:
                pass


class NonFiniteValueError(ValueError):
    """A user method returned NaN or infinity: a learner must never see it."""


def _refuse_non_finite(value: Any, method: str, env_index: int, step: int) -> None:
    """Raise when ``value`` (an observation, a dict of them, or a reward) is not finite."""
    items = value.items() if isinstance(value, Mapping) else [("", value)]
    for key, part in items:
        try:
            array = np.asarray(part, dtype=float)
        except (TypeError, ValueError):
            continue  # not numeric (a Discrete space's int is fine; text is not ours)
        if not np.all(np.isfinite(array)):
            where = f"[{key!r}]" if key else ""
            raise NonFiniteValueError(
                f"env {env_index}: {method}() returned a non-finite value{where} (NaN or "
                f"infinity) at step {step}: {array.tolist() if array.size <= 8 else array}; "
                "it was not passed to the learner. Check the solver output it reads (a "
                "diverging solver belongs in its plugin's gymprecice_detect_divergence)"
            )


def _without_label(message: str, label: str) -> str:
    """``message`` without a leading ``label`` (and the colon after it)."""
    if message.startswith(label):
        return message[len(label) :].lstrip(" :") or message
    return message


def _fit_dimensions(geometry: InterfaceGeometry, dimensions: int) -> InterfaceGeometry:
    """preCICE 2-D meshes take (x, y): drop z from 3-D coordinates of a 2-D case."""
    coords = geometry.coordinates
    if coords.shape[1] == dimensions:
        return geometry
    if coords.shape[1] == 3 and dimensions == 2:
        return InterfaceGeometry(coords[:, :2], geometry.normals, geometry.areas, geometry.patches)
    raise ValueError(
        f"interface coordinates have {coords.shape[1]} columns but the preCICE mesh is {dimensions}-D"
    )


def _lookup(produced: Mapping[Any, Any], ref: DataRef, refs: list[DataRef]) -> Any:
    """Find ``ref``'s values under its DataRef, its paper-style name, or its interface."""
    for key in (ref, str(ref)):
        if key in produced:
            return produced[key]
    if ref.interface in produced and sum(r.interface == ref.interface for r in refs) == 1:
        return produced[ref.interface]
    return None
