"""The constructor keyword arguments of the env a lab command runs, from its options.

``train``, ``evaluate`` (and ``baseline``, ``open-loop``, ``feedback``), ``sweep`` and
``benchmark`` share ``--double``, ``--case``, ``--episode-time``, ``--env-kwargs`` and the
rollout length a card names; one function turns them into the env's keyword arguments, so
the same options mean the same env in every command, and a combination the env cannot
take is refused in one line (:class:`~gymprecice_lab.common.registered_env.Refused`) before anything is
made on disk.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from gymprecice_lab.common.registered_env import LabEnv, Refused, names_where

__all__ = ["build_env_kwargs"]


def build_env_kwargs(args: argparse.Namespace, env: LabEnv, out: Path) -> dict[str, Any]:
    """Constructor keyword arguments of the environment from the command's options."""
    kwargs: dict[str, Any] = {"run_root": str((out / "envs").resolve())}
    episode_time = getattr(args, "episode_time", None)
    if args.double:
        if not env.double:
            raise Refused(
                f"gymprecice: {env.name} declares no test-double variant for --double (lab "
                f"card field 'double': pass card=EnvCard(double=True) to register() when the "
                f"env takes double=True); run it on real solvers (envs with one: "
                f"{names_where('double')})"
            )
        if args.case is not None:
            raise Refused("gymprecice: --double runs a packaged case; drop --case")
        kwargs["double"] = True
    if args.case is not None:
        if episode_time is not None:
            raise Refused(
                "gymprecice: --episode-time shapes a packaged case; with --case set the "
                "coupling's max-time in your precice-config.xml instead"
            )
        kwargs["options"] = str(args.case.resolve())
    elif episode_time is not None:
        if not env.recipe:
            raise Refused(
                f"gymprecice: {env.name} has a fixed case; --episode-time does not apply "
                "(its episode length is the coupling's max-time; an env that takes "
                "episode_time= declares the lab card field 'episode_time')"
            )
        kwargs["episode_time"] = float(episode_time)
    elif getattr(args, "rollout", False) and env.recipe and env.rollout_time:
        kwargs["episode_time"] = float(env.rollout_time)
    kwargs.update(args.env_kwargs or {})
    return kwargs
