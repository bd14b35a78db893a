"""``multi`` coupling: implicit, star-shaped around the controlling participant."""

from __future__ import annotations

from typing import TYPE_CHECKING

from gymprecice.plugin.precice_xml import CouplingSchemeSpec
from gymprecice.testing.fake_precice.config_extras import SchemeExtras
from gymprecice.testing.fake_precice.errors import PreciceError
from gymprecice.testing.fake_precice.schemes.base import Scheme
from gymprecice.testing.fake_precice.store import Flow

if TYPE_CHECKING:
    from gymprecice.testing.fake_precice.coupling import Coupling


class MultiScheme(Scheme):
    """``multi``: implicit, star-shaped around the ``control`` participant."""

    def __init__(
        self, owner: Coupling, spec: CouplingSchemeSpec, extra: SchemeExtras, local: str
    ) -> None:
        super().__init__(owner, spec, extra, local)
        if spec.control is None:
            raise PreciceError(
                "One controller per MultiCoupling needs to be defined. Please check the "
                "<participant name=... /> tags in the <coupling-scheme:... /> of your "
                "precice-config.xml. Make sure that at least one participant tag provides "
                'control="yes".'
            )
        self.controller = spec.control
        self.is_controller = spec.control == local
        self.does_first_step = not self.is_controller
        self.others = [p for p in spec.participants if p != local]
        if not self.is_controller:
            self.measures = []

    def _extra_partners(self) -> set[str]:
        return set(self.others) if self.is_controller else {self.controller}

    def _by_partner(self, flows: list[Flow]) -> dict[str, list[Flow]]:
        grouped: dict[str, list[Flow]] = {}
        for flow in flows:
            grouped.setdefault(flow.partner, []).append(flow)
        return dict(sorted(grouped.items()))

    def exchange_initial_data(self) -> None:
        sends, recvs = self._by_partner(self.send), self._by_partner(self.recv)
        if self.is_controller:
            self._initial_receive(recvs)
            self._initial_send(sends)
        else:
            self._initial_send(sends)
            self._initial_receive(recvs)

    def _initial_send(self, sends: dict[str, list[Flow]]) -> None:
        for partner, flows in sends.items():
            if any(f.initialize for f in flows):
                self.send_data(partner, flows)

    def _initial_receive(self, recvs: dict[str, list[Flow]]) -> None:
        for partner, flows in recvs.items():
            if any(f.initialize for f in flows):
                self.receive_data(partner, flows)
            else:
                self.zero_initialize(flows)

    def exchange_first_data(self) -> None:
        if self.is_controller:
            for partner, flows in self._by_partner(self.recv).items():
                self.receive_data(partner, flows)
        else:
            for partner, flows in self._by_partner(self.send).items():
                self.send_data(partner, flows)

    def exchange_second_data(self) -> None:
        if not self.is_controller:
            self.receive_convergence(self.controller)
            for partner, flows in self._by_partner(self.recv).items():
                self.receive_data(partner, flows)
        else:
            self.do_implicit_step()
            for partner in sorted(self.others):
                self.send_convergence(partner)
            for partner, flows in self._by_partner(self.send).items():
                self.send_data(partner, flows)
        if self.converged:
            self.move_to_next_window()
        self.store_iteration()
