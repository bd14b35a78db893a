"""The constructor keyword arguments of the env a lab command runs, from its options.

``train``, ``evaluate`` (and ``baseline``, ``open-loop``, ``feedback``), ``sweep`` and
``benchmark`` share ``--double``, ``--case``, ``--episode-time``, ``--env-kwargs`` and the
rollout length a card names; one function turns them into the env's keyword arguments, so
the same options mean the same env in every command, and a combination the env cannot
take is refused in one line (:class:`~gymprecice_lab.common.registered_env.Refused`) before anything is
made on disk.

The options come as any object with their five fields (:class:`EnvOptions`): a command's
settings (:class:`gymprecice_lab.common.command_settings.EnvSettings`, which builds them
once, :attr:`~gymprecice_lab.common.command_settings.EnvSettings.constructor_kwargs`).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any, Protocol

from gymprecice_lab.common.registered_env import LabEnv, Refused, names_where

__all__ = ["EnvOptions", "build_env_kwargs"]


class EnvOptions(Protocol):
    """The options that shape the env: what :func:`build_env_kwargs` reads."""

    @property
    def double(self) -> bool: ...
    @property
    def case(self) -> Path | None: ...
    @property
    def episode_time(self) -> float | None: ...
    @property
    def rollout(self) -> bool: ...
    @property
    def env_kwargs(self) -> Mapping[str, Any]: ...


def build_env_kwargs(options: EnvOptions, env: LabEnv, out: Path) -> dict[str, Any]:
    """Constructor keyword arguments of the environment from the command's options."""
    kwargs: dict[str, Any] = {"run_root": str((out / "envs").resolve())}
    episode_time = options.episode_time
    if options.double:
        if not env.double:
            raise Refused(
                f"gymprecice: {env.name} declares no test-double variant for --double (lab "
                f"card field 'double': pass card=EnvCard(double=True) to register() when the "
                f"env takes double=True); run it on real solvers (envs with one: "
                f"{names_where('double')})"
            )
        if options.case is not None:
            raise Refused("gymprecice: --double runs a packaged case; drop --case")
        kwargs["double"] = True
    if options.case is not None:
        if episode_time is not None:
            raise Refused(
                "gymprecice: --episode-time shapes a packaged case; with --case set the "
                "coupling's max-time in your precice-config.xml instead"
            )
        kwargs["options"] = str(options.case.resolve())
    elif episode_time is not None:
        if not env.recipe:
            raise Refused(
                f"gymprecice: {env.name} has a fixed case; --episode-time does not apply "
                "(its episode length is the coupling's max-time; an env that takes "
                "episode_time= declares the lab card field 'episode_time')"
            )
        kwargs["episode_time"] = float(episode_time)
    elif options.rollout and env.recipe and env.rollout_time:
        kwargs["episode_time"] = float(env.rollout_time)
    kwargs.update(options.env_kwargs or {})
    return kwargs
