"""Several coupling schemes of one participant, as preCICE's compositional scheme runs them."""

from __future__ import annotations

from gymprecice.testing.fake_precice.schemes.base import Scheme


class Composite:
    """Several schemes of one participant: explicit ones plus at most one implicit one.

    Like preCICE's ``CompositionalCouplingScheme``: while the implicit scheme iterates, the
    explicit schemes are on hold; they exchange once the implicit window has converged.
    """

    def __init__(self, schemes: list[Scheme]) -> None:
        self.explicit = [s for s in schemes if not s.implicit]
        implicit = [s for s in schemes if s.implicit]
        self.implicit_scheme = implicit[0] if implicit else None
        self.on_hold = False
        self.active: list[Scheme] = []

    @property
    def implicit(self) -> bool:
        return self.implicit_scheme is not None

    @property
    def schemes(self) -> list[Scheme]:
        return [*self.explicit, *([self.implicit_scheme] if self.implicit_scheme else [])]

    def _active_or_all(self) -> list[Scheme]:
        return self.active or self.schemes

    def initialize(self) -> None:
        for scheme in self.schemes:
            scheme.initialize()
            self.active.append(scheme)

    def add_computed_time(self, dt: float) -> bool:
        if self.implicit_scheme is None:
            at_end = False
            for scheme in self.explicit:
                at_end |= scheme.add_computed_time(dt)
            return at_end
        implicit_at_end = self.implicit_scheme.add_computed_time(dt)
        if self.on_hold:
            return implicit_at_end
        explicit_at_end = False
        for scheme in self.explicit:
            explicit_at_end |= scheme.add_computed_time(dt)
        if implicit_at_end:
            self.on_hold = True
            self._update_active()
        return implicit_at_end or explicit_at_end

    def first_exchange(self) -> None:
        if self.implicit_scheme is None:
            for scheme in self.explicit:
                scheme.first_exchange()
            return
        self.implicit_scheme.first_exchange()
        if self.on_hold:
            return
        for scheme in self.explicit:
            scheme.first_exchange()

    def second_exchange(self) -> None:
        if self.implicit_scheme is None:
            for scheme in self.explicit:
                scheme.second_exchange()
            return
        self.implicit_scheme.second_exchange()
        if not self.explicit:
            self.on_hold = False
            self._update_active()
            return
        if self.implicit_scheme.get_time() < self.explicit[0].get_time():
            return  # still iterating: the explicit schemes stay on hold
        for scheme in self.explicit:
            scheme.first_exchange()
        for scheme in self.explicit:
            scheme.second_exchange()
        self.on_hold = False
        self._update_active()

    def _update_active(self) -> None:
        if self.implicit_scheme is None:
            return
        self.active = [self.implicit_scheme]
        if not self.on_hold:
            self.active.extend(self.explicit)

    def is_ongoing(self) -> bool:
        if self.implicit_scheme is not None:
            return self.implicit_scheme.is_ongoing()
        return self.explicit[0].is_ongoing()

    def get_time(self) -> float:
        if self.implicit_scheme is not None:
            return self.implicit_scheme.get_time()
        return self.explicit[0].get_time()

    def window_start(self) -> float:
        return min(s.window_start() for s in self.schemes)

    def next_max(self) -> float:
        return min(s.next_max() for s in self.active)

    def is_window_complete(self) -> bool:
        return any(s.is_window_complete() for s in self.active)

    def action_required(self, action: str) -> bool:
        return any(s.action_required(action) for s in self._active_or_all())

    def action_fulfilled(self, action: str) -> bool:
        return any(s.action_fulfilled(action) for s in self._active_or_all())

    def mark_fulfilled(self, action: str) -> None:
        for scheme in self._active_or_all():
            if scheme.action_required(action):
                scheme.mark_fulfilled(action)

    def requires_substeps(self) -> bool:
        return any(s.requires_substeps() for s in self.schemes)

    def state_text(self) -> str:
        if len(self.schemes) == 1:
            return self.schemes[0].state_text()
        return "; ".join(
            f"partner: {' & '.join(s.partners)}, {s.state_text()}" for s in self.schemes
        )
