"""The multi-agent env: a PettingZoo ``ParallelEnv`` over one coupled simulation.

:class:`MultiAgentAdapter` holds one :class:`~gymprecice.core.Adapter` (its engine) that
runs the coupled simulation exactly as a single-agent env does: configuration, run
directory, solver launch and supervision, the watched coupling worker, the action schedule
across time windows, divergence, seeding and teardown. The engine's user methods are
answered by the multi-agent env, which splits and joins per agent:

* the agents' actions are joined into one vector, spread over the step's windows by the
  engine's schedule, and split again per window for :meth:`_get_agent_action`; so all
  agents act once per step, in one preCICE window schedule, and a terminated agent's
  actuator holds its last action while the others go on;
* :meth:`_get_observations` and :meth:`_get_rewards` return one dict for all agents.
  They are called once per step, not once per agent, because the solver outputs an env
  reads are incremental (a reader from :meth:`open_output` returns the rows that are new
  since its last read: a second agent reading it would find nothing) and because rewards
  in flow control mostly share a global term (the drag, a total displacement) that is
  computed once.

Rendering is the engine's (``render_mode="rgb_array"``, :attr:`~MultiAgentAdapter.render_fields`):
one frame of every participant's fields, with every agent's actuator drawn by
:meth:`~MultiAgentAdapter._render_overlay`; the solvers write what a frame needs only when
the env renders.
"""

from __future__ import annotations

import math
import weakref
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np

from gymprecice.tools.optional import optional_import_error

try:
    from pettingzoo import ParallelEnv
except ModuleNotFoundError as exc:  # say which extra brings it: gymprecice-core[multiagent]
    raise optional_import_error(exc, "gymprecice.multiagent") from None

from gymprecice.env.config import GymPreciceConfig
from gymprecice.env.core import Adapter, DataDict, DataRef
from gymprecice.env.frames import checked_render_mode, field_requests
from gymprecice.env.returned_values import find_written, refuse_non_finite
from gymprecice.multiagent.agents import AgentData, resolve_agents
from gymprecice.plugin.divergence import checked_penalty
from gymprecice.plugin.errors import ConfigError
from gymprecice.plugin.fields import Overlay
from gymprecice.plugin.solver import InterfaceGeometry, OutputReader

__all__ = ["MultiAgentAdapter"]


class _Slot:
    """Where one agent's action sits in the joint action vector."""

    __slots__ = ("refs", "shape", "space", "start", "stop")

    def __init__(self, start: int, space: gym.spaces.Box, refs: tuple[DataRef, ...]) -> None:
        self.start = start
        self.stop = start + int(np.prod(space.shape, dtype=int))
        self.shape = space.shape
        self.space = space
        self.refs = refs


class MultiAgentAdapter(ParallelEnv):
    """Base class of a multi-agent gymprecice environment (see :mod:`gymprecice.multiagent`).

    A subclass sets :attr:`agent_data`, fills ``self.action_spaces`` and
    ``self.observation_spaces`` (one Box action space per agent) in ``__init__`` after
    ``super().__init__(options, idx)``, and writes :meth:`_get_agent_action`,
    :meth:`_get_observations` and :meth:`_get_rewards`. The constructor's arguments are
    the :class:`~gymprecice.core.Adapter`'s, ``render_mode`` included: with
    ``render_mode="rgb_array"``, :meth:`render` returns the frame of every participant's
    :attr:`render_fields`, as the Adapter's does.
    """

    #: ``render_mode="rgb_array"``: ``render()`` draws :attr:`render_fields`, one frame per
    #: action at ``render_fps``
    metadata: ClassVar[dict[str, Any]] = {
        "name": "gymprecice-multiagent",
        "render_modes": ["rgb_array"],
        "render_fps": 4,
    }
    #: The fields ``render()`` draws, ``{solver name: field name or names}``, as the
    #: Adapter's :attr:`~gymprecice.core.Adapter.render_fields` (the first drawn below).
    render_fields: Mapping[str, str | Sequence[str]] = {}
    #: A frame's ``(width, height)`` in pixels, as the Adapter's
    render_size = Adapter.render_size
    #: agent name -> the controller's write data it drives (``"Data-interface"`` keys or
    #: interface names); every write data belongs to exactly one agent
    agent_data: ClassVar[AgentData] = {}
    #: reward of every live agent in the step in which a solver diverged (the
    #: configuration's ``environment.divergence_penalty`` overrides it)
    divergence_penalty: float = -10.0

    def __init__(
        self,
        options: Mapping[str, Any] | str | Path | None = None,
        idx: int | None = None,
        *,
        run_root: str | Path | None = None,
        case_dir: str | Path | None = None,
        render_mode: str | None = None,
    ) -> None:
        self.render_mode: str | None = checked_render_mode(render_mode, self.metadata, type(self))
        self.agents: list[str] = []
        self.possible_agents: list[str] = []
        self.observation_spaces: dict[str, gym.Space] = {}
        self.action_spaces: dict[str, gym.Space] = {}
        self._engine = _Engine(
            self, options, idx, run_root=run_root, case_dir=case_dir, render_mode=self.render_mode
        )
        owner = f"{type(self).__module__}.{type(self).__qualname__}.agent_data"
        try:
            self._agent_refs = resolve_agents(
                self.agent_data, self.config, self._engine.write_var_list, owner
            )
        except BaseException:
            self._engine.close()
            raise
        self.possible_agents = list(self._agent_refs)
        self._slots: dict[str, _Slot] = {}
        self._obs_shapes: dict[str, tuple[int, ...] | None] = {}
        self._held = np.zeros(0)

    # -- the user API ----------------------------------------------------------------------
    def _get_agent_action(
        self, agent: str, action: np.ndarray, write_var_list: list[DataRef]
    ) -> Mapping[Any, Any]:
        """Map ``agent``'s action to ``{DataRef (or its name): array}`` for its own data.

        ``write_var_list`` holds the agent's data only; it is called once per agent and
        time window, with the value the action schedule gives for that window.
        """
        raise NotImplementedError

    def _get_observations(
        self, read_data: DataDict, read_var_list: list[DataRef]
    ) -> Mapping[str, Any]:
        """``{agent: observation}`` for every live agent (see the module docstring)."""
        raise NotImplementedError

    def _get_rewards(self) -> Mapping[str, float]:
        """``{agent: reward}`` of the step that just ended, for every live agent."""
        raise NotImplementedError

    def _get_terminations(self) -> Mapping[str, bool]:
        """Agents whose task reached a terminal state (default: none; missing ones: False)."""
        return {}

    def _initial_actions(self) -> Mapping[str, np.ndarray]:
        """Each agent's actuator state at the start of an episode (default: zeros)."""
        return {agent: np.zeros(slot.shape) for agent, slot in self._slots.items()}

    def _close_external_resources(self) -> None:
        """Release files or handles the env itself opened (called at reset and close)."""

    def _render_overlay(self) -> Overlay | None:
        """Every agent's actuator state drawn over the fields; override to draw your own.

        Default: each agent's action (:attr:`last_actions`) as a line of text. Coordinates
        of arrows and markers are the fields' (the solvers' mesh coordinates).
        """
        actions = self.last_actions
        if not actions:
            return None
        return Overlay(
            text=[
                f"{agent}: {np.round(np.asarray(value, dtype=float).ravel(), 6).tolist()}"
                for agent, value in actions.items()
            ]
        )

    # -- PettingZoo API --------------------------------------------------------------------
    def observation_space(self, agent: str) -> gym.Space:
        return self._space(self.observation_spaces, "observation_spaces", agent)

    def action_space(self, agent: str) -> gym.Space:
        return self._space(self.action_spaces, "action_spaces", agent)

    def reset(
        self, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, Any], dict[str, dict[str, Any]]]:
        self.agents = []
        self._layout()
        # render_fields checked here, so that a mistake names this class, not the engine
        field_requests(type(self), self.render_mode, self.render_fields, self.config)
        self.agents = list(self.possible_agents)
        try:
            obs, info = self._engine.reset(seed=seed, options=options)
        except BaseException:
            self.agents = []
            raise
        self._held = np.array(self._engine.schedule_start, dtype=float)
        return (
            {agent: obs[agent] for agent in self.agents},
            {agent: dict(info) for agent in self.agents},
        )

    def step(
        self, actions: Mapping[str, Any]
    ) -> tuple[
        dict[str, Any],
        dict[str, float],
        dict[str, bool],
        dict[str, bool],
        dict[str, dict[str, Any]],
    ]:
        live = self.agents
        if not live:
            raise gym.error.ResetNeeded(
                "every agent is done (or the env was never reset); call reset() before step()"
            )
        joint = self._joint(actions, live)
        try:
            obs, _, terminated, truncated, info = self._engine.step(joint)
        except BaseException:
            self.agents = []  # the engine ended the episode and killed its solvers
            raise
        self._held = joint
        if "diverged" in info:
            penalty = self._engine.penalty
            rewards = dict.fromkeys(live, penalty)
            terms = dict.fromkeys(live, True)
            truncs = dict.fromkeys(live, False)
        else:
            rewards = self._engine.rewards
            ended = self._engine.terminations
            terms = {agent: terminated or agent in ended for agent in live}
            truncs = {agent: truncated and not terms[agent] for agent in live}
        self.agents = [agent for agent in live if not (terms[agent] or truncs[agent])]
        return (
            {agent: obs[agent] for agent in live},
            rewards,
            terms,
            truncs,
            {agent: dict(info) for agent in live},
        )

    def close(self) -> None:
        """End everything this env started; safe to call any number of times."""
        self.agents = []
        self._engine.close()

    def render(self) -> np.ndarray | None:
        """The physics at the current step as an ``(H, W, 3)`` uint8 frame (``rgb_array``).

        Every field of :attr:`render_fields` is read from its solver's plugin at the
        current coupling time and drawn in one frame, every agent's actuator
        (:meth:`_render_overlay`) on top. Without ``render_mode`` this returns ``None``
        with a warning, as PettingZoo's and Gymnasium's envs do.
        """
        if self.render_mode is None:
            gym.logger.warn(
                f"{self._who()}.render() called without a render_mode; make the env with "
                'render_mode="rgb_array"'
            )
            return None
        return self._engine.render()

    # -- the Adapter's documented API, for the user's methods --------------------------------
    @property
    def config(self) -> GymPreciceConfig:
        return self._engine.config

    @property
    def env_index(self) -> int:
        return self._engine.env_index

    @property
    def time(self) -> float:
        """Coupling time: 0 at ``reset()``, the end of the step after ``step()``."""
        return self._engine.time

    @property
    def time_window(self) -> int:
        return self._engine.time_window

    @property
    def dt(self) -> float | None:
        return self._engine.dt

    @property
    def end_time(self) -> float | None:
        return self._engine.end_time

    @property
    def np_random(self) -> np.random.Generator:
        """The env's random generator, seeded by ``reset(seed=...)``."""
        return self._engine.np_random

    @property
    def env_dir(self) -> Path:
        return self._engine.env_dir

    @property
    def run_dir(self) -> Path:
        return self._engine.run_dir

    @property
    def solver_dirs(self) -> dict[str, Path]:
        return self._engine.solver_dirs

    @property
    def interface_geometry(self) -> dict[str, InterfaceGeometry]:
        return self._engine.interface_geometry

    @property
    def write_var_list(self) -> list[DataRef]:
        return self._engine.write_var_list

    @property
    def read_var_list(self) -> list[DataRef]:
        return self._engine.read_var_list

    @property
    def last_actions(self) -> dict[str, np.ndarray]:
        """The action each agent's actuator holds: its last one (a done agent's too), the
        initial action after ``reset()``; ``{}`` before the first reset."""
        if not self._slots or len(self._held) != self._engine.action_space.shape[0]:
            return {}
        return {
            agent: self._held[slot.start : slot.stop].reshape(slot.shape).copy()
            for agent, slot in self._slots.items()
        }

    @property
    def agent_write_data(self) -> dict[str, list[DataRef]]:
        """Each agent's write data, resolved from :attr:`agent_data`."""
        return {agent: list(refs) for agent, refs in self._agent_refs.items()}

    def set_interface_vertices(self, interface: str, coordinates: Any) -> None:
        """See :meth:`gymprecice.core.Adapter.set_interface_vertices`."""
        self._engine.set_interface_vertices(interface, coordinates)

    def open_output(self, solver: str, name: str, /, **options: Any) -> OutputReader:
        """See :meth:`gymprecice.core.Adapter.open_output`."""
        return self._engine.open_output(solver, name, **options)

    # -- internals -------------------------------------------------------------------------
    def _who(self) -> str:
        return type(self).__qualname__

    def _space(self, spaces: Mapping[str, gym.Space], attr: str, agent: str) -> gym.Space:
        try:
            return spaces[agent]
        except KeyError:
            if agent not in self._agent_refs:
                raise KeyError(
                    f"{self._who()}: no agent {agent!r}; the agents are {self.possible_agents}"
                ) from None
            raise ConfigError(
                f"{self._who()} sets no {attr}[{agent!r}]: fill self.{attr} for every agent "
                f"({self.possible_agents}) in __init__, after super().__init__()"
            ) from None

    def _layout(self) -> None:
        """Place each agent's action in the joint vector; its spaces must be set and Boxes.

        The joint vector is what the engine's action schedule spreads over the windows of
        a step (hold, ramp, cosine, filter), so an action must be numbers: a Box.
        """
        slots: dict[str, _Slot] = {}
        start = 0
        lows, highs = [], []
        for agent in self.possible_agents:
            space = self.action_space(agent)
            self.observation_space(agent)
            if not isinstance(space, gym.spaces.Box):
                raise ConfigError(
                    f"{self._who()}: action_spaces[{agent!r}] is {space}; a gymprecice agent "
                    "acts through a Box (its actions are spread over the step's time windows "
                    "as numbers): use a Box, and map a discrete choice to values in "
                    "_get_agent_action"
                )
            slot = _Slot(start, space, self._agent_refs[agent])
            slots[agent] = slot
            start = slot.stop
            lows.append(np.broadcast_to(space.low, space.shape).ravel())
            highs.append(np.broadcast_to(space.high, space.shape).ravel())
        self._slots = slots
        self._engine.action_space = gym.spaces.Box(
            np.concatenate(lows).astype(float), np.concatenate(highs).astype(float), dtype=float
        )
        self._obs_shapes = {
            agent: space.shape if isinstance(space, gym.spaces.Box) else None
            for agent, space in self.observation_spaces.items()
        }
        self._engine.observation_space = gym.spaces.Dict(
            {agent: self.observation_space(agent) for agent in self.possible_agents}
        )

    def _joint(self, actions: Mapping[str, Any], live: list[str]) -> np.ndarray:
        """One vector of every agent's action; a done agent's part holds its last action."""
        if not isinstance(actions, Mapping):
            raise TypeError(
                f"{self._who()}.step() takes a dict {{agent: action}} for every live agent "
                f"({live}), got {type(actions).__name__}"
            )
        if actions.keys() != set(live):
            self._refuse_agents(actions, live)
        joint = self._held.copy()
        for agent in live:
            slot = self._slots[agent]
            value = actions[agent]
            if np.shape(value) != slot.shape:
                raise ValueError(
                    f"{self._who()}: the action of agent {agent!r} has shape "
                    f"{np.shape(value)}, but its action space {slot.space} expects shape "
                    f"{slot.shape}"
                )
            try:
                joint[slot.start : slot.stop] = np.ravel(value)
            except (TypeError, ValueError):
                raise ValueError(
                    f"{self._who()}: the action of agent {agent!r} is not numeric "
                    f"({value!r}); its action space is {slot.space}"
                ) from None
        if not np.isfinite(joint).all():
            bad = [
                a
                for a in live
                if not np.isfinite(joint[self._slots[a].start : self._slots[a].stop]).all()
            ]
            raise ValueError(
                f"{self._who()}: the action of agent(s) {bad} is not finite (NaN or infinity); "
                "check the policy's output"
            )
        return joint

    def _refuse_agents(self, actions: Mapping[str, Any], live: list[str]) -> None:
        missing = [agent for agent in live if agent not in actions]
        unknown = [agent for agent in actions if agent not in self._agent_refs]
        done = [agent for agent in actions if agent in self._agent_refs and agent not in live]
        problems = []
        if missing:
            problems.append(f"no action for agent(s) {missing}")
        if unknown:
            problems.append(f"action(s) for unknown agent(s) {unknown}")
        if done:
            problems.append(f"action(s) for agent(s) {done}, done in this episode")
        raise ValueError(
            f"{self._who()}.step(): {'; '.join(problems)}. Give exactly one action per live "
            f"agent, env.agents = {live} (the agents are {self.possible_agents})"
        )

    def _check_observations(self, obs: Any) -> None:
        """The observations cover the live agents, and each fits its agent's space."""
        live = self.agents
        if not isinstance(obs, Mapping):
            raise TypeError(
                f"{self._who()}._get_observations() returned {type(obs).__name__}; return a "
                f"dict {{agent: observation}} for the live agents {live}"
            )
        if not all(agent in obs for agent in live) or len(obs) > len(live):
            missing = [agent for agent in live if agent not in obs]
            unknown = [key for key in obs if key not in self._agent_refs]
            if missing or unknown:
                raise KeyError(
                    f"{self._who()}._get_observations() returned observations for {list(obs)}: "
                    + (f"none for live agent(s) {missing}" if missing else "")
                    + ("; " if missing and unknown else "")
                    + (f"unknown agent(s) {unknown}" if unknown else "")
                    + f". The agents are {self.possible_agents}"
                )
        shapes = self._obs_shapes
        for agent in live:
            value = obs[agent]
            shape = shapes[agent]
            space = self.observation_spaces[agent]
            if shape is not None:  # a Box: its shape (bounds are the learner's business)
                fits = getattr(value, "shape", None) == shape or np.shape(value) == shape
            else:
                fits = space.contains(value)
            if not fits:
                what = f"shape {np.shape(value)}" if shape is not None else repr(value)
                raise ValueError(
                    f"{self._who()}._get_observations() returned for agent {agent!r} an "
                    f"observation of {what}, which observation_spaces[{agent!r}] = {space} "
                    "does not hold: make the space and the method agree"
                )

    def _checked_rewards(self, rewards: Any) -> dict[str, float]:
        live = self.agents
        if not isinstance(rewards, Mapping):
            raise TypeError(
                f"{self._who()}._get_rewards() returned {type(rewards).__name__}; return a "
                f"dict {{agent: reward}} for the live agents {live}"
            )
        missing = [agent for agent in live if agent not in rewards]
        unknown = [key for key in rewards if key not in self._agent_refs]
        if missing or unknown:
            raise KeyError(
                f"{self._who()}._get_rewards() returned rewards for {list(rewards)}: "
                + (f"none for live agent(s) {missing}" if missing else "")
                + ("; " if missing and unknown else "")
                + (f"unknown agent(s) {unknown}" if unknown else "")
                + f". The agents are {self.possible_agents}"
            )
        out = {agent: float(rewards[agent]) for agent in live}
        if not math.isfinite(math.fsum(out.values())):  # one NaN or infinity makes it so
            refuse_non_finite(out, "_get_rewards", self.env_index, self._engine.steps)
        return out

    def _agent_writes(self, value: np.ndarray) -> dict[DataRef, Any]:
        """Every agent's data for one window's joint action ``value``."""
        out: dict[DataRef, Any] = {}
        for agent, slot in self._slots.items():
            refs = slot.refs
            produced = self._get_agent_action(
                agent, value[slot.start : slot.stop].reshape(slot.shape), list(refs)
            )
            if not isinstance(produced, Mapping):
                raise TypeError(
                    f"{self._who()}._get_agent_action({agent!r}, ...) returned "
                    f"{type(produced).__name__}; return a dict keyed by the entries of its "
                    f"write_var_list {[str(r) for r in refs]}"
                )
            for ref in refs:
                array = produced.get(ref)
                if array is None:
                    array = find_written(produced, ref, list(refs))
                if array is None:
                    raise KeyError(
                        f"{self._who()}._get_agent_action({agent!r}, ...) returned no data for "
                        f"{ref} (interface {ref.interface!r}, data {ref.data!r}); return a "
                        f"dict keyed by the entries of its write_var_list "
                        f"{[str(r) for r in refs]}"
                    )
                out[ref] = array
            if len(produced) > len(refs):
                self._refuse_foreign(agent, produced, refs)
        return out

    def _refuse_foreign(self, agent: str, produced: Mapping[Any, Any], refs: tuple) -> None:
        own = {key for ref in refs for key in (ref, str(ref), ref.interface)}
        for key in produced:
            if key in own:
                continue
            owner = next(
                (a for a, rs in self._agent_refs.items() for r in rs if key in (r, str(r))),
                None,
            )
            whose = f"agent {owner!r}'s data" if owner else "not a write data of this env"
            raise KeyError(
                f"{self._who()}._get_agent_action({agent!r}, ...) returned {str(key)!r}, "
                f"which is {whose}; an agent writes only its own: "
                f"{[str(r) for r in refs]} (agent_data)"
            )


class _Engine(Adapter):
    """The one coupled run behind a :class:`MultiAgentAdapter`; its user methods ask it.

    It holds its multi-agent env weakly: the env owns the engine, not the other way round,
    so dropping the env lets both go (the engine's exit-time cleanup still finds a running
    episode through the Adapter's own registry).
    """

    def __init__(self, owner: MultiAgentAdapter, *args: Any, **kwargs: Any) -> None:
        self._owner_ref = weakref.ref(owner)
        self.metadata = owner.metadata  # the render modes the owner supports and checked
        super().__init__(*args, **kwargs)
        if self.config.model.environment.divergence_penalty is None:
            cls = type(owner)
            self._gymprecice.guards.penalty = checked_penalty(
                cls.divergence_penalty, cls.__qualname__, "divergence_penalty"
            )
        #: the last step's rewards of the live agents, and the agents its task ended
        self.rewards: dict[str, float] = {}
        self.terminations: set[str] = set()
        #: the joint action the episode started from
        self.schedule_start = np.zeros(0)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> Any:
        """The Adapter's reset; one that fails in the user's methods leaves nothing running."""
        try:
            return super().reset(seed=seed, options=options)
        except BaseException:
            self._gymprecice.end_episode(abort=True)
            raise

    def step(self, action: Any) -> Any:
        """The Adapter's step; one that fails in the user's methods ends the episode.

        The multi-agent env has no live agent after an error, so the solvers of the
        episode would only wait for the next reset: they are stopped at once.
        """
        try:
            return super().step(action)
        except BaseException:
            self._gymprecice.end_episode(abort=True)
            raise

    @property
    def penalty(self) -> float:
        return self._gymprecice.guards.penalty

    @property
    def steps(self) -> int:
        return self._gymprecice.steps

    def _owner(self) -> MultiAgentAdapter:
        owner = self._owner_ref()
        if owner is None:
            raise ReferenceError("the multi-agent env of this engine is gone")
        return owner

    def _get_action(self, action: Any, write_var_list: list[DataRef]) -> Mapping[Any, Any]:
        return self._owner()._agent_writes(np.asarray(action, dtype=float))

    def _get_observation(self, read_data: DataDict, read_var_list: list[DataRef]) -> Any:
        owner = self._owner()
        obs = owner._get_observations(read_data, read_var_list)
        owner._check_observations(obs)
        return obs

    def _get_reward(self) -> float:
        self.rewards = self._owner()._checked_rewards(self._owner()._get_rewards())
        return float(sum(self.rewards.values()))

    def _get_terminated(self) -> bool:
        owner = self._owner()
        flags = owner._get_terminations()
        if not flags:
            self.terminations = set()
            return False
        unknown = [key for key in flags if key not in owner._agent_refs]
        if unknown:
            raise KeyError(
                f"{owner._who()}._get_terminations() names unknown agent(s) {unknown}; the "
                f"agents are {owner.possible_agents}"
            )
        live = owner.agents
        self.terminations = {agent for agent in live if flags.get(agent)}
        return len(self.terminations) == len(live)

    def _initial_action(self) -> np.ndarray:
        owner = self._owner()
        initial = owner._initial_actions()
        joint = np.zeros(self.action_space.shape, dtype=float)
        for agent, slot in owner._slots.items():
            if agent not in initial:
                raise KeyError(
                    f"{owner._who()}._initial_actions() has no entry for agent {agent!r}"
                )
            values = np.asarray(initial[agent], dtype=float)
            if values.shape != slot.shape:
                raise ValueError(
                    f"{owner._who()}._initial_actions()[{agent!r}] has shape {values.shape}; "
                    f"action_spaces[{agent!r}] expects {slot.shape}"
                )
            joint[slot.start : slot.stop] = values.ravel()
        self.schedule_start = joint
        self.terminations = set()
        return joint

    def _close_external_resources(self) -> None:
        owner = self._owner_ref()
        if owner is not None:
            owner._close_external_resources()

    # -- rendering: the owner's fields, frame size and overlay
    @property
    def render_fields(self) -> Mapping[str, str | Sequence[str]]:  # type: ignore[override]
        return self._owner().render_fields

    @property
    def render_size(self) -> tuple[int, int]:  # type: ignore[override]
        return self._owner().render_size

    def _render_overlay(self) -> Overlay | None:
        return self._owner()._render_overlay()
