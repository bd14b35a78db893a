"""``serial-*`` and ``parallel-*`` coupling between two participants."""

from __future__ import annotations

from typing import TYPE_CHECKING

from gymprecice.plugin.precice_xml import CouplingSchemeSpec
from gymprecice.testing.fake_precice.config_extras import SchemeExtras
from gymprecice.testing.fake_precice.schemes.base import Scheme

if TYPE_CHECKING:
    from gymprecice.testing.fake_precice.coupling import Coupling


class BiScheme(Scheme):
    """``serial-*`` and ``parallel-*``: two participants, ``first`` and ``second``."""

    def __init__(
        self, owner: Coupling, spec: CouplingSchemeSpec, extra: SchemeExtras, local: str
    ) -> None:
        super().__init__(owner, spec, extra, local)
        self.serial = spec.serial
        self.does_first_step = spec.first == local
        self.partner = spec.second if self.does_first_step else spec.first

    def _extra_partners(self) -> set[str]:
        return {str(self.partner)}

    def exchange_initial_data(self) -> None:
        p = self.partner
        if self.serial:
            if self.does_first_step:
                if self.receives_initialized:
                    self.receive_data(p, self.recv)
                else:
                    self.zero_initialize(self.recv)
                if self.sends_initialized:
                    self.send_data(p, self.send)
            else:
                if self.sends_initialized:
                    self.send_data(p, self.send)
                if self.receives_initialized:
                    self.receive_data(p, self.recv)
                self.receive_data_for_window_end(p, self.recv)
        elif self.does_first_step:
            if self.sends_initialized:
                self.send_data(p, self.send)
            if self.receives_initialized:
                self.receive_data(p, self.recv)
            else:
                self.zero_initialize(self.recv)
        else:
            if self.receives_initialized:
                self.receive_data(p, self.recv)
            else:
                self.zero_initialize(self.recv)
            if self.sends_initialized:
                self.send_data(p, self.send)

    def exchange_first_data(self) -> None:
        p = self.partner
        if self.serial:
            if not self.implicit or self.does_first_step:
                self.send_data(p, self.send)
            else:
                self.do_implicit_step()
                self.send_convergence(p)
                self.send_data(p, self.send)
        elif self.does_first_step:
            self.send_data(p, self.send)
        else:
            self.receive_data(p, self.recv)

    def exchange_second_data(self) -> None:
        if self.serial:
            self._serial_second()
        else:
            self._parallel_second()

    def _serial_second(self) -> None:
        p = self.partner
        if not self.implicit:
            if self.does_first_step:
                self.receive_data(p, self.recv)
            self.move_to_next_window()
            if not self.does_first_step and self.is_ongoing():
                self.receive_data_for_window_end(p, self.recv)
            return
        if self.does_first_step:
            self.receive_convergence(p)
            self.receive_data(p, self.recv)
        if self.converged:
            self.move_to_next_window()
        self.store_iteration()
        if not self.does_first_step and (self.is_ongoing() or not self.converged):
            if self.converged:
                self.receive_data_for_window_end(p, self.recv)
            else:
                self.receive_data(p, self.recv)

    def _parallel_second(self) -> None:
        p = self.partner
        if not self.implicit:
            if self.does_first_step:
                self.receive_data(p, self.recv)
            else:
                self.send_data(p, self.send)
            self.move_to_next_window()
            return
        if self.does_first_step:
            self.receive_convergence(p)
            self.receive_data(p, self.recv)
        else:
            self.do_implicit_step()
            self.send_convergence(p)
            self.send_data(p, self.send)
        if self.converged:
            self.move_to_next_window()
        self.store_iteration()
