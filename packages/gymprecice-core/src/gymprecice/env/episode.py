"""An Adapter's episodes: reset and step as plumbing between the user's methods and the run.

:class:`EpisodeRunner` is what a :class:`~gymprecice.core.Adapter` holds: it composes the
:class:`~gymprecice.coupled_run.CoupledRun` (run directory, solvers, coupling session),
the :class:`~gymprecice.guards.Guards` (divergence, solver health, finite values), the
:class:`~gymprecice.action_shaping.ActionShaper` (an action spread over time windows and
written), the :class:`~gymprecice.vertices.ControllerVertices` and the
:class:`~gymprecice.frames.Frames` of ``render()``, and keeps the episode's bookkeeping.
It keeps no reference to its env: each call takes the env, whose user methods it calls
and whose documented attributes (``time``, ``time_window``, ``dt``, ``last_action``) it
updates, so dropping the env ends its episode at once (:meth:`EpisodeRunner.collected`).
"""

from __future__ import annotations

import logging
import math
import time
from pathlib import Path
from typing import Any

import gymnasium as gym

from gymprecice.env import exit_cleanup
from gymprecice.env.action_shaping import ActionShaper
from gymprecice.env.coupled_run import CoupledRun
from gymprecice.env.coupling import CouplingState
from gymprecice.env.frames import Frames, field_requests
from gymprecice.env.guards import Guards
from gymprecice.env.returned_values import NonFiniteValueError
from gymprecice.env.values import DataDict, DataRef, Timing
from gymprecice.env.vertices import ControllerVertices
from gymprecice.plugin.divergence import Divergence, checked_penalty
from gymprecice.plugin.errors import CouplingError, SolverError

__all__ = ["EpisodeRunner", "shown_time"]

log = logging.getLogger("gymprecice.core")

#: The env a runner serves: a :class:`gymprecice.core.Adapter` (core imports this module,
#: so this one names the type without importing it).
Adapter = Any

Step = tuple[Any, float, bool, bool, dict[str, Any]]


class EpisodeRunner:
    """The machinery of one Adapter (see the module docstring).

    ``idx`` and ``run_root`` are the Adapter's arguments. ``cls`` is the class whose
    ``divergence_penalty`` counts unless the configuration sets one: the env's own by
    default, the multi-agent env's for the view it hands the runner.
    """

    def __init__(
        self,
        env: Adapter,
        idx: int | None,
        run_root: str | Path | None,
        *,
        cls: type | None = None,
    ) -> None:
        config = env.config
        cls = type(env) if cls is None else cls
        configured = config.model.environment.divergence_penalty
        penalty = checked_penalty(
            cls.divergence_penalty if configured is None else configured,
            config.where() if configured is not None else cls.__qualname__,
            "environment.divergence_penalty" if configured is not None else "divergence_penalty",
        )
        self.run = CoupledRun(config, idx, run_root)
        self.guards = Guards(self.run, penalty)
        self.write_refs = [
            DataRef(i.name, i.mesh, d) for i in config.interfaces.values() for d in i.write
        ]
        self.read_refs = [
            DataRef(i.name, i.mesh, d) for i in config.interfaces.values() for d in i.read
        ]
        self.actions = ActionShaper(config, self.write_refs)
        self.vertices = ControllerVertices(config, self.run)
        self.frames = Frames(self.run)
        self.active = False
        #: the episode ended (truncated or terminated) and awaits a reset
        self.over = False
        self.closed = False
        #: steps taken in the current episode
        self.steps = 0
        self.last_read: DataDict = DataDict()
        #: the last observation handed out: what a diverged step returns
        self.last_obs: Any = None

    # -- reset -----------------------------------------------------------------------------
    def reset(self, env: Adapter, options: dict[str, Any] | None) -> tuple[Any, dict[str, Any]]:
        """End any running episode, then start the solvers and the coupling anew."""
        started = time.perf_counter()
        self.end_episode(abort=True)
        self.run.close_readers()
        env._close_external_resources()
        if self.closed:  # reset() after close() reopens the env: close() works again
            self.closed = False
            self.run.reclaim()
        self.run.prepare()
        # From here on solvers may run: exit-time cleanup and SIGTERM/SIGHUP must find them,
        # including during this first reset.
        exit_cleanup.track(env)
        session, registry = self.run.open_session(
            health_check=self.guards.health_check, watch=self.guards.watch_solver
        )
        try:
            seed = int(env.np_random.integers(2**63 - 1))
            fields = field_requests(type(env), env.render_mode, env.render_fields, env.config)
            self.run.launch(
                session,
                registry,
                seed=seed,
                options=options,
                fields=fields,
                field_interval=self.actions.frame_interval(env.config.time_window_size),
            )
            schedule = self.actions.schedule
            schedule.start(env._initial_action())
            env.last_action = schedule.current
            initial = self._written(env, schedule.current)
            state = self.run.initialize(
                session,
                {
                    spec.mesh: env.interface_geometry[spec.name].coordinates
                    for spec in env.config.interfaces.values()
                    if not spec.direct
                },
                {
                    spec.mesh: self.vertices.access_region(spec)
                    for spec in env.config.interfaces.values()
                    if spec.direct
                },
                initial,
            )
        except BaseException:
            self.end_episode(abort=True)
            raise
        self.active = True
        self.over = False
        self._apply(env, state)
        self.steps = 0
        obs = self._observed(env)
        return obs, self._info(env, state, {"reset_s": time.perf_counter() - started})

    # -- step ------------------------------------------------------------------------------
    def step(self, env: Adapter, action: Any) -> Step:
        """Spread ``action`` over the step's windows, advance, observe and reward."""
        session = self.run.session
        if not self.active or session is None:
            if self.over:
                raise gym.error.ResetNeeded(
                    "the episode has ended (truncated or terminated); call reset() before step()"
                )
            raise gym.error.ResetNeeded("call reset() before step()")
        started = time.perf_counter()
        action = self.actions.checked(action, env.action_space, env.env_index)
        env.last_action = action
        windows = self.actions.windows_left(env.time, env.dt, env.end_time)
        spread = self.actions.schedule.spread(action, windows)
        writes = [self._written(env, value) for value in spread]
        env_s = time.perf_counter() - started
        waited = time.perf_counter()
        try:
            state = self.run.advance(session, writes)
        except (SolverError, CouplingError) as exc:
            return self._failed(env, exc, session, started)
        except BaseException:
            # Ctrl-C, or SystemExit from the user's own signal handler: the episode cannot
            # go on, and nothing of it may outlive this env.
            self.end_episode(abort=True)
            raise
        evidence = self.guards.watch_all(session, env.time)
        if evidence is not None:  # diverging, though the step itself completed
            self.end_episode(abort=True)
            return self._diverged(env, evidence, started)
        wait_s = time.perf_counter() - waited
        self._apply(env, state)
        self.steps += 1
        after = time.perf_counter()
        self.run.output_wait[0] = 0.0
        try:
            obs = self._observed(env)
            reward = self.guards.reward(env._get_reward(), env.env_index, self.steps)
        except (SolverError, CouplingError) as exc:  # a solver died while its output was awaited
            return self._failed(env, exc, session, started)
        except NonFiniteValueError:
            # NaN forces are what a diverging flow writes first; its log may lag behind
            # its output files (buffered), so give the plugins a moment to confirm.
            evidence = self.guards.confirm_divergence(session, env.time)
            self.end_episode(abort=True)
            if evidence is None:
                raise
            return self._diverged(env, evidence, started)
        terminated = bool(env._get_terminated())
        truncated = not state.ongoing and not terminated
        output_wait = self.run.output_wait[0]
        wait_s += output_wait  # waiting for a solver's files is waiting for the solver
        env_s += time.perf_counter() - after - output_wait
        if terminated or truncated:
            # Finalizing and waiting for the solvers to exit is waiting for the solvers
            # (tens of ms on the last step); without this it would fall in no bucket.
            finishing = time.perf_counter()
            self.end_episode(abort=terminated and state.ongoing)
            wait_s += time.perf_counter() - finishing
            self.over = True
        timing = {
            "precice_s": state.precice_s,
            "wait_s": wait_s,
            "env_s": env_s,
            "step_s": time.perf_counter() - started,
        }
        return obs, reward, terminated, truncated, self._info(env, state, timing)

    def _failed(self, env: Adapter, exc: Exception, session: Any, started: float) -> Step:
        """A step whose coupling or solver failed: its divergence, or the error again."""
        self.end_episode(abort=True)
        divergence = self.guards.divergence(exc, session, env.time)
        if divergence is None:
            raise exc
        return self._diverged(env, divergence, started)

    def _diverged(self, env: Adapter, divergence: Divergence, started: float) -> Step:
        """The terminal step of a diverged episode: last observation, the penalty."""
        self.over = True
        log.info(
            "env %d: solver %r diverged at t=%g: %s",
            env.env_index,
            divergence.solver,
            divergence.time,
            divergence.evidence,
        )
        info = {
            "time": env.time,
            "time_window": env.time_window,
            "env_index": env.env_index,
            "diverged": divergence.as_info(),
            "timing": Timing({"step_s": time.perf_counter() - started}),
        }
        return self.last_obs, self.guards.penalty, True, False, info

    # -- what a step hands to the user and back ---------------------------------------------
    def _written(self, env: Adapter, value: Any) -> dict[tuple[str, str], Any]:
        return self.actions.written(value, env._get_action, lambda: env.interface_geometry)

    def _observed(self, env: Adapter) -> Any:
        """The user's observation, refused if it holds NaN or infinity."""
        obs = env._get_observation(self.last_read, env.read_var_list)
        self.last_obs = self.guards.observation(obs, env.env_index, self.steps)
        return obs

    def _apply(self, env: Adapter, state: CouplingState) -> None:
        """The coupling's state after a reset or step, on the env and its geometry."""
        self.vertices.set_direct(state.coordinates)
        env.time = state.time
        env.time_window = state.windows
        if state.dt:
            env.dt = state.dt
        by_key = {(ref.mesh, ref.data): ref for ref in self.read_refs}
        self.last_read = DataDict({by_key[key]: value for key, value in state.read.items()})

    def _info(self, env: Adapter, state: CouplingState, timing: dict[str, float]) -> dict:
        return {
            "time": shown_time(state.time, env.dt),
            "time_window": state.windows,
            "env_index": env.env_index,
            "timing": Timing(timing),
        }

    # -- render ----------------------------------------------------------------------------
    def render(self, env: Adapter) -> Any:
        """The frame of ``env.render()`` (see :class:`~gymprecice.frames.Frames`)."""
        if env.render_mode is None:
            gym.logger.warn(
                f"{type(env).__name__}.render() called without a render_mode; make the env "
                'with render_mode="rgb_array"'
            )
            return None
        if self.run.session is None and not self.over:
            raise gym.error.ResetNeeded("call reset() before render()")
        requests = field_requests(type(env), env.render_mode, env.render_fields, env.config)
        return self.frames.draw(
            requests,
            time=env.time,
            window=env.dt,
            size=env.render_size,
            overlay=env._render_overlay,
            title=(
                f"{env.config.model.environment.name}   t = {env.time:.4g} s   step {self.steps}"
            ),
        )

    # -- ending ----------------------------------------------------------------------------
    def end_episode(self, *, abort: bool) -> None:
        """Kill (or finish) the running episode's session (see :meth:`CoupledRun.end`)."""
        self.active = False
        self.run.end(abort=abort)

    def close(self, env: Adapter) -> None:
        """End everything ``env`` started; safe to call any number of times."""
        if self.closed and self.run.session is None:
            return
        self.closed = True
        try:
            self.end_episode(abort=True)
            self.run.close_readers()
            env._close_external_resources()
        finally:
            self.run.kill_recorded()
            exit_cleanup.forget(env)
            self.run.release_claim()

    def collected(self) -> None:
        """The env was garbage-collected: end its episode and free its index."""
        try:
            if not self.closed:
                self.end_episode(abort=True)
            self.run.release_claim()
        except Exception:
            pass


def shown_time(time: float, window: float | None) -> float:
    """``time`` rounded to about a millionth of the time window: 2.0, not 2.0000000000000013.

    Adding up windows leaves noise in the last digits of the coupling time. A millionth of a
    window is far above that noise and far below any time step the coupling can take, so
    the times of one window compare equal and those of two different ones never do.
    """
    if not window or window <= 0 or not math.isfinite(time) or not math.isfinite(window):
        return time
    return round(time, max(0, 6 - math.floor(math.log10(window))))
