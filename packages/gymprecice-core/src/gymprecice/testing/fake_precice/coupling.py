"""What one participant couples through: its channels, its data store, its data shapes."""

from __future__ import annotations

from collections.abc import Callable

from gymprecice.testing.fake_precice.channel import Channel
from gymprecice.testing.fake_precice.errors import PreciceError
from gymprecice.testing.fake_precice.store import Key, Store


class Coupling:
    """The state the coupling schemes share with their participant.

    Built with the participant (the schemes hold it from the start); ``initialize`` fills
    in the channels to the partners and the shape of every (data, mesh). ``log`` is the
    participant's preCICE-style log, which the schemes write to as preCICE's do.
    """

    def __init__(self, name: str, degrees: dict[str, int], log: Callable[[str], None]) -> None:
        self.name = name
        self.log = log
        self.store = Store(degrees)
        self.channels: dict[str, Channel] = {}
        self.shapes: dict[Key, tuple[int, int]] = {}

    def channel(self, partner: str) -> Channel:
        """The channel to ``partner``; preCICE's advice where no m2n tag connects them."""
        try:
            return self.channels[partner]
        except KeyError:
            raise PreciceError(
                f'There is no m2n communication between participants "{self.name}" and '
                f'"{partner}", but they exchange data. Please add an <m2n:sockets '
                f'acceptor="{self.name}" connector="{partner}" /> tag to the preCICE '
                "configuration."
            ) from None
