"""The Adapter: a Gymnasium environment whose physics is a preCICE-coupled simulation.

A user writes an environment by subclassing :class:`Adapter`, setting ``action_space`` and
``observation_space``, and overriding the Gym-preCICE paper's methods, three of them
required:

* ``_get_action(action, write_var_list)``: turn an action into data for each interface;
* ``_get_observation(read_data, read_var_list)``: turn coupling data and/or solver outputs
  into an observation;
* ``_get_reward()``: the reward of the step that just ended;
* ``_close_external_resources()`` (optional): release what the env itself opened;
* ``_get_terminated()`` (optional, default ``False``): a real terminal state was reached;
* ``_initial_action()`` (optional, default zeros): the actuators' state at reset.

Everything generic is done by core: configuration, the env's run directory, preparing,
resetting and launching solvers through plugins, the preCICE participant (in a watched
worker process), time windows and the smoothing of actions across them, seeding, and
clean teardown. Reaching the coupling's end time truncates the episode (a time limit, not
a terminal state). A solver that diverges under the agent's actions terminates it, with
the env's ``divergence_penalty`` as reward and ``info["diverged"]`` (see
:mod:`gymprecice.divergence`); a non-finite observation or reward from the user's methods
is refused with the method's name and the step, never handed to the learner.

A subclass shares its namespace with the Adapter, so the Adapter keeps in it only the
user methods above and the documented API; the machinery lives in one object it holds,
``_gymprecice`` (an :class:`~gymprecice.episode.EpisodeRunner`: the coupled run, the
guards and the action shaping), which a subclass leaves alone.
"""

from __future__ import annotations

import weakref
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from gymprecice.env.config import GymPreciceConfig, check_solver_kinds, load_config
from gymprecice.env.episode import EpisodeRunner
from gymprecice.env.frames import checked_render_mode
from gymprecice.env.returned_values import NonFiniteValueError as NonFiniteValueError
from gymprecice.env.timed_reader import OUTPUT_WAIT_SLICE_S as OUTPUT_WAIT_SLICE_S
from gymprecice.env.values import DataDict, DataRef, Timing
from gymprecice.plugin.errors import ConfigError
from gymprecice.plugin.fields import Overlay
from gymprecice.plugin.manager import plugin_failures, solver_kinds
from gymprecice.plugin.solver import LIBRARY_ENV_VAR as LIBRARY_ENV_VAR
from gymprecice.plugin.solver import InterfaceGeometry, OutputReader

__all__ = ["Adapter", "DataDict", "DataRef", "Timing"]


class Adapter(gym.Env):
    """Base class of every gymprecice environment (see the module docstring)."""

    #: ``render_mode="rgb_array"``: ``render()`` draws :attr:`render_fields` (see
    #: :meth:`render`); ``render_fps`` is a video's frame rate (one frame per action).
    metadata: dict[str, Any] = {"render_modes": ["rgb_array"], "render_fps": 4}
    #: The fields ``render()`` draws: ``{solver name: field name or names}``, asked of each
    #: solver's plugin (``gymprecice_read_field``), drawn in this order (the first below).
    render_fields: Mapping[str, str | Sequence[str]] = {}
    #: A frame's ``(width, height)`` in pixels. Height ``None`` (the default): the first
    #: frame sets it from the drawn domain's aspect ratio (a wide channel, a wide frame),
    #: a multiple of 16 pixels, and it is kept (see :func:`gymprecice.rendering.frame_height`).
    #: Fixed sizes: multiples of 16 suit video encoders.
    render_size: tuple[int, int | None] = (640, None)
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
        render_mode: str | None = None,
    ) -> None:
        """Load and check the configuration; nothing is copied or started before ``reset()``.

        ``options`` is the configuration: a path to ``gymprecice-config.json``, the case
        directory holding one, or the parsed dict (both of its forms, explicit and the
        Gym-preCICE paper's; relative paths in a dict are taken from ``case_dir``, default
        the working directory). It is checked against the preCICE XML and the installed
        plugins here, and a :class:`~gymprecice.errors.ConfigError` names the file, the
        key and the fix. ``idx`` is the env's index, its run directory ``env_<idx>``; left
        out, the env claims the lowest index no live env under the same run root holds
        (a lock held until :meth:`close`, across processes too). ``run_root`` is where the
        env's run directory goes, overriding ``environment.run_root`` of the
        configuration (default ``gymprecice-runs`` in the working directory): the env's
        copy of the case, solver logs and outputs, and preCICE's exchange files, so it
        belongs on a fast local disk. ``case_dir`` overrides the directory the
        configuration's relative paths start from (default: the file's own directory).
        ``render_mode`` is Gymnasium's (see ``render()``).
        """
        super().__init__()
        self.render_mode = checked_render_mode(render_mode, self.metadata, type(self))
        if options is None:
            raise ConfigError(
                "Adapter needs its configuration: a path to gymprecice-config.json (or the case "
                "directory holding it), or the parsed dict"
            )
        #: the checked configuration (both config files)
        self.config: GymPreciceConfig = load_config(options, case_dir=case_dir)
        check_solver_kinds(self.config, solver_kinds(), plugin_failures())
        runner = EpisodeRunner(self, idx, run_root)
        #: core's machinery of this env: leave it to core
        self._gymprecice = runner
        # Dropping the env ends its episode and frees its index at once (no __del__ in the
        # namespace a subclass shares).
        weakref.finalize(self, runner.collected).atexit = False
        #: the env's index: its run directory is ``env_<env_index>``
        self.env_index: int = runner.run.env_index
        #: coupling time (0 at reset) and time windows completed in this episode
        self.time = 0.0
        self.time_window = 0
        #: the coupling's time window size and end time (``None`` where it has none)
        self.dt: float | None = self.config.time_window_size
        self.end_time: float | None = self.config.end_time
        #: the last action taken (the initial action after reset): what overlays draw
        self.last_action: Any = None

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

    def _render_overlay(self) -> Overlay | None:
        """The actuators' state drawn over the fields; override to draw your own.

        Default: the last action's values as text. Coordinates of arrows and markers are
        the fields' (the solvers' mesh coordinates).
        """
        if self.last_action is None:
            return None
        values = np.round(np.asarray(self.last_action, dtype=float).ravel(), 6).tolist()
        return Overlay(text=[f"action {values}"])

    # -- geometry, directories and outputs -------------------------------------------------
    @property
    def env_dir(self) -> Path:
        """Where this env's run directory is (or will be), without preparing anything.

        A supervisor needs it before preparation starts, to find the pid registry of a
        preparation that hangs.
        """
        return self._gymprecice.run.env_dir

    @property
    def run_dir(self) -> Path:
        """This env's run directory (made and prepared on first use)."""
        return self._gymprecice.run.prepare().root

    @property
    def solver_dirs(self) -> dict[str, Path]:
        """Each solver's copy of its case, by solver name (prepared on first use)."""
        run = self._gymprecice.run
        run.prepare()
        return {name: ctx.run_dir for name, ctx in run.solvers.items()}

    @property
    def write_var_list(self) -> list[DataRef]:
        """The data the controller writes, one :class:`DataRef` each."""
        return list(self._gymprecice.write_refs)

    @property
    def read_var_list(self) -> list[DataRef]:
        """The data the controller reads, one :class:`DataRef` each."""
        return list(self._gymprecice.read_refs)

    @property
    def interface_geometry(self) -> dict[str, InterfaceGeometry]:
        """Vertices (and normals/areas where a plugin knows them) of every interface."""
        return self._gymprecice.vertices.known()

    def set_interface_vertices(self, interface: str, coordinates: Any) -> None:
        """Set the controller vertices of ``interface`` by hand (overrides plugins)."""
        self._gymprecice.vertices.set(interface, coordinates)

    def _set_precice_vectices(self, coords: Mapping[str, Any]) -> None:
        """Gym-preCICE v0.1 spelling: ``{"write_to": {name: coords}, "read_from": {...}}``."""
        groups = coords.values() if {"write_to", "read_from"} & set(coords) else [coords]
        for group in groups:
            for name, value in group.items():
                self.set_interface_vertices(name, value)

    def open_output(self, solver: str, name: str, /, **options: Any) -> OutputReader:
        """An incremental reader of a solver output, e.g. ``open_output("fluid", "probes")``.

        The same arguments give the same reader until the episode ends, so an env can ask
        for it in every ``_get_observation`` and read only what is new; core closes every
        reader at reset and close.
        """
        return self._gymprecice.run.open_output(solver, name, options)

    # -- Gymnasium API ---------------------------------------------------------------------
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]:
        super().reset(seed=seed)
        return self._gymprecice.reset(self, options)

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        return self._gymprecice.step(self, action)

    def render(self) -> np.ndarray | None:
        """The physics at the current step as an ``(H, W, 3)`` uint8 frame (``rgb_array``).

        Every field of :attr:`render_fields` is read from its solver's plugin at the
        current coupling time and drawn in one frame, with :meth:`_render_overlay` (the
        actuators' state) on top. Without ``render_mode`` this returns ``None`` with a
        warning, as Gymnasium's envs do.
        """
        return self._gymprecice.render(self)

    def close(self) -> None:
        """End everything this env started; safe to call any number of times.

        A call made while another one waits out the kill grace (a SIGTERM handler, a
        second Ctrl-C) does not return early: it kills what is left at once. Whatever the
        pid registry still records (a solver started an instant before an interrupt) is
        killed last. ``reset()`` after ``close()`` reopens the env.
        """
        self._gymprecice.close(self)
