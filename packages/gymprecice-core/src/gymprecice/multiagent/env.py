"""The multi-agent env: a PettingZoo ``ParallelEnv`` over one coupled simulation.

:class:`MultiAgentAdapter` runs its coupled simulation on the
:class:`~gymprecice.episode.EpisodeRunner` an :class:`~gymprecice.core.Adapter` runs on
(configuration, run directory, solver launch and supervision, the watched coupling
worker, the action schedule across time windows, divergence, seeding and teardown). The
runner serves one env with one action; the multi-agent env hands it a
:class:`~gymprecice.multiagent.view.JointView` of itself, which splits and joins per
agent:

* the agents' actions are joined into one vector, spread over the step's windows by the
  runner's schedule, and split again per window for :meth:`_get_agent_action`; so all
  agents act once per step, in one preCICE window schedule, and a terminated agent's
  actuator holds its last action while the others go on;
* :meth:`_get_observations` and :meth:`_get_rewards` return one dict for all agents.
  They are called once per step, not once per agent, because the solver outputs an env
  reads are incremental (a reader from :meth:`open_output` returns the rows that are new
  since its last read: a second agent reading it would find nothing) and because rewards
  in flow control mostly share a global term (the drag, a total displacement) that is
  computed once.

Rendering is the runner's (``render_mode="rgb_array"``, :attr:`~MultiAgentAdapter.render_fields`):
one frame of every participant's fields, with every agent's actuator drawn by
:meth:`~MultiAgentAdapter._render_overlay`; the solvers write what a frame needs only when
the env renders.

A subclass shares its namespace with the env, so the env keeps in it only the user
methods, PettingZoo's API and the documented attributes; the machinery is in two objects
it holds, ``_gymprecice`` (the runner, as an Adapter's) and ``_view`` (what the runner
sees: the agents' layout, their last rewards and terminations), which a subclass leaves
alone.
"""

from __future__ import annotations

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

from gymprecice.env.config import check_solver_kinds, load_config
from gymprecice.env.core import Adapter, DataDict, DataRef
from gymprecice.env.frames import checked_render_mode, field_requests
from gymprecice.multiagent.agents import AgentData, resolve_agents
from gymprecice.multiagent.layout import AgentLayout, agent_space
from gymprecice.multiagent.view import AgentMethods, JointView
from gymprecice.plugin.errors import ConfigError
from gymprecice.plugin.fields import Overlay
from gymprecice.plugin.manager import plugin_failures, solver_kinds
from gymprecice.plugin.solver import OutputReader

__all__ = ["MultiAgentAdapter"]


def _adapter_attribute(name: str) -> Any:
    """A read-only attribute that is the Adapter's ``name``, as the env's view keeps it."""
    return property(
        lambda self: getattr(self._view, name),
        doc=f"The Adapter's ``{name}`` (see :class:`~gymprecice.core.Adapter`).",
    )


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
    #: reward of every live agent in the step in which a solver diverged, as the Adapter's
    #: (the configuration's ``environment.divergence_penalty`` overrides it)
    divergence_penalty: float = Adapter.divergence_penalty

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
        if options is None:
            raise ConfigError(
                f"{type(self).__name__} needs its configuration: a path to "
                "gymprecice-config.json (or the case directory holding it), or the parsed dict"
            )
        config = load_config(options, case_dir=case_dir)
        check_solver_kinds(config, solver_kinds(), plugin_failures())
        methods = AgentMethods.held_weakly(
            agent_action=self._get_agent_action,
            observations=self._get_observations,
            rewards=self._get_rewards,
            terminations=self._get_terminations,
            initial_actions=self._initial_actions,
            close_external_resources=self._close_external_resources,
            render_overlay=self._render_overlay,
        )
        view = JointView(self, methods, config, idx, run_root, render_mode=self.render_mode)
        #: what the runner sees of this env: leave it to core
        self._view = view
        #: core's machinery of this env, as an Adapter's: leave it to core
        self._gymprecice = view.runner
        # Dropping the env ends its episode and frees its index at once (no __del__ in the
        # namespace a subclass shares).
        weakref.finalize(self, view.runner.collected).atexit = False
        owner = f"{type(self).__module__}.{type(self).__qualname__}.agent_data"
        try:
            view.agent_refs = resolve_agents(self.agent_data, config, view.write_var_list, owner)
        except BaseException:
            self._gymprecice.close(view)
            raise
        self.possible_agents = list(view.agent_refs)

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
        return {agent: np.zeros(self.action_space(agent).shape) for agent in self.possible_agents}

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
        return agent_space(
            self.observation_spaces,
            "observation_spaces",
            agent,
            list(self._view.agent_refs),
            type(self).__qualname__,
        )

    def action_space(self, agent: str) -> gym.Space:
        return agent_space(
            self.action_spaces,
            "action_spaces",
            agent,
            list(self._view.agent_refs),
            type(self).__qualname__,
        )

    def reset(
        self, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, Any], dict[str, dict[str, Any]]]:
        view = self._view
        self.agents = []
        view.layout = AgentLayout.of(
            self.possible_agents,
            view.agent_refs,
            self.action_space,
            self.observation_space,
            type(self).__qualname__,
        )
        # render_fields checked here, so that a mistake names this class, not the view
        field_requests(type(self), self.render_mode, self.render_fields, self.config)
        self.agents = list(self.possible_agents)
        try:
            view.seed(seed)
            obs, info = self._gymprecice.reset(view, options)
        except BaseException:
            # no agent is live after an error, so the episode's solvers would only wait for
            # the next reset: they are stopped at once
            self.agents = []
            self._gymprecice.end_episode(abort=True)
            raise
        view.held = np.array(view.start, dtype=float)
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
        view = self._view
        joint = view.joint(actions, live)
        try:
            obs, _, terminated, truncated, info = self._gymprecice.step(view, joint)
        except BaseException:  # as in reset(): the episode's solvers are stopped at once
            self.agents = []
            self._gymprecice.end_episode(abort=True)
            raise
        view.held = joint
        if "diverged" in info:
            penalty = self._gymprecice.guards.penalty
            rewards = dict.fromkeys(live, penalty)
            terms = dict.fromkeys(live, True)
            truncs = dict.fromkeys(live, False)
        else:
            rewards = view.rewards
            terms = {agent: terminated or agent in view.terminations for agent in live}
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
        self._gymprecice.close(self._view)

    def render(self) -> np.ndarray | None:
        """The physics at the current step as an ``(H, W, 3)`` uint8 frame (``rgb_array``).

        Every field of :attr:`render_fields` is read from its solver's plugin at the
        current coupling time and drawn in one frame, every agent's actuator
        (:meth:`_render_overlay`) on top. Without ``render_mode`` this returns ``None``
        with a warning, as PettingZoo's and Gymnasium's envs do.
        """
        if self.render_mode is None:
            gym.logger.warn(
                f"{type(self).__qualname__}.render() called without a render_mode; make the "
                'env with render_mode="rgb_array"'
            )
            return None
        return self._gymprecice.render(self._view)

    # -- the Adapter's documented API, for the user's methods --------------------------------
    config = _adapter_attribute("config")
    """The checked configuration (both config files)."""
    env_index = _adapter_attribute("env_index")
    """The env's index: its run directory is ``env_<env_index>``."""
    time = _adapter_attribute("time")
    """Coupling time: 0 at ``reset()``, the end of the step after ``step()``."""
    time_window = _adapter_attribute("time_window")
    """Time windows completed in this episode."""
    dt = _adapter_attribute("dt")
    """The coupling's time window size (``None`` where it has none)."""
    end_time = _adapter_attribute("end_time")
    """The coupling's end time (``None`` where it has none)."""
    np_random = _adapter_attribute("np_random")
    """The env's random generator, seeded by ``reset(seed=...)``."""
    env_dir = _adapter_attribute("env_dir")
    """Where this env's run directory is (or will be), without preparing anything."""
    run_dir = _adapter_attribute("run_dir")
    """This env's run directory (made and prepared on first use)."""
    solver_dirs = _adapter_attribute("solver_dirs")
    """Each solver's copy of its case, by solver name (prepared on first use)."""
    interface_geometry = _adapter_attribute("interface_geometry")
    """Vertices (and normals/areas where a plugin knows them) of every interface."""
    write_var_list = _adapter_attribute("write_var_list")
    """The data the controller writes, one :class:`~gymprecice.core.DataRef` each."""
    read_var_list = _adapter_attribute("read_var_list")
    """The data the controller reads, one :class:`~gymprecice.core.DataRef` each."""

    @property
    def last_actions(self) -> dict[str, np.ndarray]:
        """The action each agent's actuator holds: its last one (a done agent's too), the
        initial action after ``reset()``; ``{}`` before the first reset."""
        return self._view.last_actions()

    @property
    def agent_write_data(self) -> dict[str, list[DataRef]]:
        """Each agent's write data, resolved from :attr:`agent_data`."""
        return {agent: list(refs) for agent, refs in self._view.agent_refs.items()}

    def set_interface_vertices(self, interface: str, coordinates: Any) -> None:
        """See :meth:`gymprecice.core.Adapter.set_interface_vertices`."""
        self._view.set_interface_vertices(interface, coordinates)

    def open_output(self, solver: str, name: str, /, **options: Any) -> OutputReader:
        """See :meth:`gymprecice.core.Adapter.open_output`."""
        return self._view.open_output(solver, name, options)
