"""One coupling scheme as one participant sees it: time, actions, convergence, messages."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from gymprecice.plugin.precice_xml import CouplingSchemeSpec
from gymprecice.testing.fake_precice.clock import Time
from gymprecice.testing.fake_precice.config_extras import SchemeExtras
from gymprecice.testing.fake_precice.errors import PreciceError
from gymprecice.testing.fake_precice.numerics import greater_equals, num
from gymprecice.testing.fake_precice.store import Flow, Key

if TYPE_CHECKING:
    from gymprecice.testing.fake_precice.coupling import Coupling


INITIALIZE_DATA = "write-initial-data"
WRITE_CHECKPOINT = "write-iteration-checkpoint"
READ_CHECKPOINT = "read-iteration-checkpoint"


class Scheme:
    """Time, actions and convergence of one coupling scheme, as one participant sees it.

    Subclasses only say who sends and receives what, in which order; that order is the
    one of preCICE's ``SerialCouplingScheme``, ``ParallelCouplingScheme`` and
    ``MultiCouplingScheme``, so both ends of every socket agree on every message.
    """

    def __init__(
        self, owner: Coupling, spec: CouplingSchemeSpec, extra: SchemeExtras, local: str
    ) -> None:
        self.owner = owner
        self.spec = spec
        self.local = local
        self.implicit = spec.implicit
        self.max_windows = spec.max_time_windows
        self.window_size = float(spec.time_window_size or 0.0)
        self.next_window_size = self.window_size
        self.time = Time(spec.max_time)
        self.time_windows = 1
        self.iterations = 1
        self.total_iterations = 1
        self.min_iterations = extra.min_iterations if self.implicit else 1
        self.max_iterations = spec.max_iterations if self.implicit else None
        self.measures = [m for m in extra.measures] if self.implicit else []
        self.required: set[str] = set()
        self.fulfilled: set[str] = set()
        self.initialized = False
        self.window_complete = False
        self.converged = False
        self.does_first_step = True
        self.previous: dict[Key, np.ndarray] = {}
        self.iterations_log: Path | None = None
        self.convergence_log: Path | None = None
        self.send: list[Flow] = []
        self.recv: list[Flow] = []
        default_substeps = self.implicit
        for exchange, substeps in zip(spec.exchanges, extra.substeps):
            sub = default_substeps if substeps is None else substeps
            if exchange.from_participant == local:
                self.send.append(
                    Flow(
                        exchange.data,
                        exchange.mesh,
                        exchange.to_participant,
                        exchange.initialize,
                        sub,
                    )
                )
            elif exchange.to_participant == local:
                self.recv.append(
                    Flow(
                        exchange.data,
                        exchange.mesh,
                        exchange.from_participant,
                        exchange.initialize,
                        sub,
                    )
                )
        self.sends_initialized = any(f.initialize for f in self.send)
        self.receives_initialized = any(f.initialize for f in self.recv)
        if self.sends_initialized:
            self.required.add(INITIALIZE_DATA)
        if self.implicit and not self.measures and self.max_iterations is None:
            raise PreciceError(
                "Not defining convergence measures without providing a maximum iteration limit "
                "is forbidden. Please define a convergence measure or set a maximum iteration "
                'limit using <max-iterations value="..." />.'
            )

    # -- bookkeeping shared with the compositional scheme

    @property
    def keys(self) -> list[Key]:
        return [f.key for f in (*self.send, *self.recv)]

    @property
    def partners(self) -> list[str]:
        return sorted({f.partner for f in (*self.send, *self.recv)} | self._extra_partners())

    def _extra_partners(self) -> set[str]:
        return set()

    def action_required(self, action: str) -> bool:
        return action in self.required

    def action_fulfilled(self, action: str) -> bool:
        return action in self.fulfilled

    def mark_fulfilled(self, action: str) -> None:
        self.fulfilled.add(action)

    def requires_substeps(self) -> bool:
        return any(f.substeps for f in self.send)

    def get_time(self) -> float:
        return self.time.time()

    def window_start(self) -> float:
        return self.time.start.total

    def is_ongoing(self) -> bool:
        windows_left = self.max_windows is None or self.max_windows >= self.time_windows
        return windows_left and not self.time.reached_end()

    def is_window_complete(self) -> bool:
        return self.window_complete

    def next_max(self) -> float:
        if not self.is_ongoing():
            return 0.0
        return self.time.until_window_end(self.window_size)

    def reached_end_of_window(self) -> bool:
        return self.time.reached_end_of_window(self.window_size)

    # -- the advance cycle (BaseCouplingScheme)

    def initialize(self) -> None:
        self.owner.store.zero_at(self.recv, 0.0, self.owner.shapes)
        self.time.reset_to(0.0)
        self.time_windows = 1
        for flow in self.send:
            if not len(self.owner.store.wave(flow.key)):
                raise PreciceError(
                    f"Data {flow.data} on mesh {flow.mesh} doesn't contain any samples while "
                    f"initializing a coupling scheme of participant {self.local}. There are two "
                    f"common configuration issues that may cause this. Either, make sure "
                    f"participant {self.local} specifies data {flow.data} to be written using "
                    f'tag <write-data mesh="{flow.mesh}" data="{flow.data}"/>. Or ensure '
                    f"participant {self.local} defines a mapping to mesh {flow.mesh} from a mesh "
                    f"using data {flow.data}."
                )
        if self.implicit:
            self.store_iteration()
            self.required.add(WRITE_CHECKPOINT)
            self.iterations_log = Path(f"precice-{self.local}-iterations.log")
            self.iterations_log.write_text("  TimeWindow  TotalIterations  Iterations  Convergence")
            if not self.does_first_step:
                self.convergence_log = Path(f"precice-{self.local}-convergence.log")
                columns = ["TimeWindow", "Iteration", *(m.header for m in self.measures)]
                self.convergence_log.write_text("".join(f"  {c}" for c in columns))
        self.exchange_initial_data()
        self.initialized = True

    def add_computed_time(self, dt: float) -> bool:
        if not greater_equals(self.next_max(), dt):
            raise PreciceError(
                f'The time step size given to preCICE in "advance" {dt!r} exceeds the maximum '
                f"allowed time step size {self.next_max()!r} in the remaining of this time "
                'window. Did you restrict your time step size, "dt = min(preciceDt, solverDt)"? '
                "For more information, consult the adapter example in the preCICE documentation."
            )
        self.time.progress_by(dt)
        return self.reached_end_of_window()

    def check_actions(self) -> None:
        if INITIALIZE_DATA in self.required and INITIALIZE_DATA not in self.fulfilled:
            raise PreciceError(
                'Data was not initialized. Did you forget to call "requiresWritingData()"?'
            )
        if READ_CHECKPOINT in self.required and READ_CHECKPOINT not in self.fulfilled:
            raise PreciceError(
                "The iteration checkpoint wasn't read. Did you forget to call "
                '"requiresReadingCheckpoint()"?'
            )
        if WRITE_CHECKPOINT in self.required and WRITE_CHECKPOINT not in self.fulfilled:
            raise PreciceError(
                "The iteration checkpoint wasn't written. Did you forget to call "
                '"requiresWritingCheckpoint()"?'
            )
        self.required.clear()
        self.fulfilled.clear()

    def first_exchange(self) -> None:
        self.check_actions()
        self.window_complete = False
        if self.reached_end_of_window():
            self.time_windows += 1
            self.exchange_first_data()

    def second_exchange(self) -> None:
        self.check_actions()
        if not self.reached_end_of_window():
            return
        self.exchange_second_data()
        if self.implicit:
            if not self.converged:
                self.required.add(READ_CHECKPOINT)
                self.time_windows -= 1
                self.window_complete = False
            else:
                self._log_iterations()
                self.owner.log("Time window completed")
                self.window_complete = True
                if self.is_ongoing():
                    self.required.add(WRITE_CHECKPOINT)
            self.total_iterations += 1
            self.iterations = 1 if self.converged else self.iterations + 1
        else:
            self.owner.log("Time window completed")
            self.window_complete = True
        if self.window_complete:
            self.time.complete_window(self.window_size)
        else:
            self.time.reset_progress()
        self.window_size = self.next_window_size

    def _log_iterations(self) -> None:
        if self.iterations_log is None:
            return
        limit_ok = self.max_iterations is None or self.iterations < self.max_iterations
        converged = int(self.iterations >= self.min_iterations and limit_ok)
        row = (
            f"\n{self.time_windows - 1:>6}  {self.total_iterations:>6}  "
            f"{self.iterations:>6}  {converged:>6}"
        )
        with self.iterations_log.open("a") as fh:
            fh.write(row)

    def do_implicit_step(self) -> None:
        self.converged = self.measure_convergence()
        if self.max_iterations is not None and self.iterations == self.max_iterations:
            self.converged = True
        if self.converged:
            for measure in self.measures:
                measure.first_residual = None

    def measure_convergence(self) -> bool:
        row = f"\n{self.time_windows - 1:>6}  {self.iterations:>6}"
        if not self.measures:
            self._log_convergence(row)
            return False
        all_converged, one_suffices, one_strict = True, False, False
        for measure in self.measures:
            key = (measure.data, measure.mesh)
            new = self.owner.store.wave(key).last()
            converged, residual = measure.measure(self.previous[key], new)
            row += f"  {residual:>15.8e}"
            if not converged:
                all_converged = False
                if measure.strict:
                    one_strict = True
                    if self.max_iterations is not None and self.iterations >= self.max_iterations:
                        raise PreciceError(
                            f'The strict convergence measure for data "{measure.data}" did not '
                            "converge within the maximum allowed iterations, which terminates "
                            "the simulation. To avoid this forced termination do not mark the "
                            "convergence measure as strict."
                        )
            elif measure.suffices:
                one_suffices = True
        self._log_convergence(row)
        enough = self.iterations >= self.min_iterations
        return enough and (all_converged or (one_suffices and not one_strict))

    def _log_convergence(self, row: str) -> None:
        if self.convergence_log is not None:
            with self.convergence_log.open("a") as fh:
                fh.write(row)

    def store_iteration(self) -> None:
        for key in self.keys:
            self.previous[key] = self.owner.store.wave(key).last().copy()

    def move_to_next_window(self) -> None:
        self.owner.store.move(self.keys)

    # -- communication helpers

    def send_data(self, partner: str, flows: list[Flow]) -> None:
        entries, arrays = self.owner.store.payload(flows)
        self.owner.channel(partner).send("data", entries, arrays)

    def receive_data(self, partner: str, flows: list[Flow], at: float | None = None) -> None:
        entries, arrays = self.owner.channel(partner).recv("data")
        self.owner.store.deliver(flows, entries, arrays, self.get_time() if at is None else at)

    def receive_data_for_window_end(self, partner: str, flows: list[Flow]) -> None:
        self.receive_data(
            partner,
            flows,
            at=self.time.start.plus(self.time.progress.total + self.next_window_size),
        )

    def send_convergence(self, partner: str) -> None:
        self.owner.channel(partner).send("convergence", bool(self.converged))

    def receive_convergence(self, partner: str) -> None:
        value, _ = self.owner.channel(partner).recv("convergence")
        self.converged = bool(value)

    def zero_initialize(self, flows: list[Flow]) -> None:
        self.owner.store.zero_at(flows, self.get_time(), self.owner.shapes)

    # -- to be provided by the concrete schemes

    def exchange_initial_data(self) -> None:
        raise NotImplementedError

    def exchange_first_data(self) -> None:
        raise NotImplementedError

    def exchange_second_data(self) -> None:
        raise NotImplementedError

    def state_text(self) -> str:
        """preCICE's ``printCouplingState``, logged after ``initialize`` and every ``advance``."""
        if not self.is_ongoing():
            return (
                f"Reached end at: final time-window: {self.time_windows - 1}, "
                f"final time: {num(self.get_time())}"
            )
        text = ""
        if self.implicit:
            limits = [f"min: {self.min_iterations}"]
            if self.max_iterations is not None:
                limits.append(f"max: {self.max_iterations}")
            text += f"it {self.iterations} ({', '.join(limits)}), "
        text += f"time-window {self.time_windows}"
        if self.max_windows is not None:
            text += f" (max: {self.max_windows})"
        text += f", t {num(self.get_time())}"
        if self.time.max_time is not None:
            text += f" (max: {num(self.time.max_time)})"
        text += f", Dt {num(self.window_size)}, max-dt {num(self.next_max())}"
        return text
