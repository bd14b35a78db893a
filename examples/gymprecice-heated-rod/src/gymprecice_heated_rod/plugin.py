"""The package's gymprecice plugin: registers HeatedRod-v0 and its lab card.

gymprecice loads this module through the ``gymprecice`` entry point
(pyproject.toml) on every ``import gymprecice``, so it stays light: the env
class is named by a ``"module:Class"`` string (Gymnasium imports it only in
``make``) and the feedback law by ``"module:attribute"`` (the lab imports it
only when a command needs it).
"""

from __future__ import annotations

from collections.abc import Callable

from gymprecice.card import EnvCard
from gymprecice.hookspecs import hookimpl

ENV_ID = "heatedrod/HeatedRod-v0"

CARD = EnvCard(
    name="heated-rod",
    description="hold a heated rod's temperature at a setpoint under a load",
    objective="tracking_error",
    metrics=("tracking_error", "mean_temperature", "heat"),
    held_out_starts=True,
    uncontrolled={"uncontrolled": True},
    feedback_law="gymprecice_heated_rod.control:PI_LAW",
    double=True,
    open_loop_frequency=2.0,
    action_unit="K/s",
)


@hookimpl
def gymprecice_register_environments(register: Callable[..., None]) -> None:
    register(ENV_ID, "gymprecice_heated_rod.env:HeatedRodEnv", card=CARD)
