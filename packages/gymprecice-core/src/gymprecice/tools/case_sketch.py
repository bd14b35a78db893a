"""A whole case's sketch: each solver's plugin answer, and what the coupling makes of it.

A plugin says what its solver's case holds (:class:`~gymprecice.sketch.SolverSketch`:
patches, the domain's loops, probes, the vertices of its preCICE meshes). What a patch is
*for* is read here from the preCICE configuration, the same for every solver kind:

* a patch carrying a preCICE mesh that the controller writes to is an ``actuator``
  (the jets, the spinning wall, the flap's inlet, the plate's heater);
* one whose mesh another solver's participant exchanges data on is an ``interface``
  (the flap's FSI interface, the plate's CHT interface);
* otherwise it keeps the kind the solver's boundary conditions give it.

The controller's vertices are the solver mesh's vertices where the controller couples
to it (what it writes, and what it reads: the plate's interface temperature); every
participant's watch points come from the preCICE configuration. A solver no plugin
sketches is listed in :attr:`CaseSketch.undrawn`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from gymprecice.env.config import GymPreciceConfig, pristine_context
from gymprecice.plugin.manager import get_plugin_manager
from gymprecice.plugin.precice_xml import PreciceConfig
from gymprecice.plugin.sketch import SolverSketch

__all__ = ["CaseSketch", "DrawnPatch", "DrawnPoints", "Region", "sketch_case", "solver_sketches"]


@dataclass(frozen=True, eq=False)
class DrawnPatch:
    """A patch as the sketch draws it: ``kind`` includes ``actuator`` and ``interface``.

    ``role`` says what the coupling does there (``"controller writes Velocity"``,
    ``"FSI with Solid"``); empty for a patch nobody couples on.
    """

    solver: str
    name: str
    kind: str
    segments: np.ndarray
    role: str = ""


@dataclass(frozen=True, eq=False)
class DrawnPoints:
    """Points the sketch marks: ``kind`` is ``probe``, ``watch point``, ``controller
    reads`` or ``controller writes``; ``names`` label each point (watch points)."""

    kind: str
    label: str
    points: np.ndarray
    names: tuple[str, ...] = ()


@dataclass(frozen=True, eq=False)
class Region:
    """A solver's domain: the loops bounding it (filled with the solver's colour)."""

    solver: str
    label: str
    loops: tuple[np.ndarray, ...]


@dataclass
class CaseSketch:
    """Everything ``gymprecice sketch`` draws of one case, as data (tests read this)."""

    title: str
    regions: list[Region] = field(default_factory=list)
    patches: list[DrawnPatch] = field(default_factory=list)
    points: list[DrawnPoints] = field(default_factory=list)
    #: the solvers no installed plugin sketches: ``"solid (dealii)"``
    undrawn: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    def patch(self, name: str, solver: str | None = None) -> DrawnPatch:
        """The patch ``name`` (of ``solver`` where two solvers share a name)."""
        for patch in self.patches:
            if patch.name == name and solver in (None, patch.solver):
                return patch
        raise KeyError(f"no patch {name!r}; the sketch has {[p.name for p in self.patches]}")


def solver_sketches(config: GymPreciceConfig) -> dict[str, SolverSketch | None]:
    """Each solver's plugin answer (``None``: no plugin sketches that solver)."""
    hook = get_plugin_manager().hook
    answers: dict[str, SolverSketch | None] = {}
    for name in config.solvers:
        answer = hook.gymprecice_sketch_case(solver=pristine_context(config, name))
        if answer is not None and not isinstance(answer, SolverSketch):
            raise TypeError(
                f"gymprecice_sketch_case answered {type(answer).__name__} for solver {name!r}; "
                "a plugin returns a gymprecice.sketch.SolverSketch or None"
            )
        answers[name] = answer
    return answers


def _partners(precice: PreciceConfig, participant: str, mesh: str, controller: str) -> list[str]:
    """The solver participants other than ``participant`` that couple on its ``mesh``."""
    found = []
    own = precice.participants.get(participant)
    for other in precice.participants.values():
        if other.name in (participant, controller):
            continue
        mapped = [
            m
            for holder in (own, other)
            if holder is not None
            for m in holder.mappings
            if mesh in (m.from_mesh, m.to_mesh)
            and ({m.from_mesh, m.to_mesh} - {mesh}) & set(other.provided_meshes)
        ]
        if mesh in other.received_meshes or mapped:
            found.append(other.name)
    return found


def _role(config: GymPreciceConfig, participant: str | None, meshes: tuple[str, ...]):
    """(kind or None, role text, written meshes, read meshes) of a patch's meshes."""
    writes, reads, partners = [], [], []
    for interface in config.interfaces.values():
        if interface.partner != participant or interface.partner_mesh not in meshes:
            continue
        if interface.write:
            writes.append((interface, interface.partner_mesh))
        if interface.read:
            reads.append((interface, interface.partner_mesh))
    if participant is not None:
        for mesh in meshes:
            for other in _partners(config.precice, participant, mesh, config.participant):
                if other not in partners:
                    partners.append(other)
    parts = []
    if writes:
        data = sorted({d for i, _ in writes for d in i.write})
        parts.append(f"controller writes {', '.join(data)}")
    if reads:
        data = sorted({d for i, _ in reads for d in i.read})
        parts.append(f"controller reads {', '.join(data)}")
    if partners:
        parts.append(f"coupled with {', '.join(partners)}")
    kind = "actuator" if writes else "interface" if partners else None
    return kind, "; ".join(parts), writes, reads


def sketch_case(
    config: GymPreciceConfig, title: str, answers: dict[str, SolverSketch | None] | None = None
) -> CaseSketch:
    """The case of ``config`` as one :class:`CaseSketch` (``answers``: the plugins',
    asked here when not given)."""
    answers = solver_sketches(config) if answers is None else answers
    sketch = CaseSketch(title=title)
    controller_points: dict[tuple[str, str], list[np.ndarray]] = {}
    for name, answer in answers.items():
        spec = config.solvers[name]
        if answer is None:
            sketch.undrawn.append(f"{name} ({spec.kind})")
            continue
        who = f"{name} ({spec.kind}{', ' + spec.participant if spec.participant else ''})"
        if answer.loops:
            sketch.regions.append(Region(name, who, answer.loops))
        sketch.notes.extend(f"{name}: {note}" for note in answer.notes)
        for patch in answer.patches:
            kind, role, writes, reads = _role(config, spec.participant, patch.meshes)
            sketch.patches.append(
                DrawnPatch(name, patch.name, kind or patch.kind, patch.segments, role)
            )
            for what, pairs in (("writes", writes), ("reads", reads)):
                for interface, mesh in pairs:
                    if mesh in answer.vertices:
                        data = interface.write if what == "writes" else interface.read
                        key = (what, ", ".join(data))
                        controller_points.setdefault(key, []).append(answer.vertices[mesh])
        for points in answer.points:
            sketch.points.append(DrawnPoints("probe", points.label or points.name, points.points))
    for (what, data), arrays in controller_points.items():
        unique = np.unique(np.concatenate(arrays), axis=0)
        label = f"controller {what} {data} ({len(unique)} vertices)"
        sketch.points.append(DrawnPoints(f"controller {what}", label, unique))
    watch = [
        (participant.name, point)
        for participant in config.precice.participants.values()
        for point in participant.watch_points
    ]
    if watch:
        sketch.points.append(
            DrawnPoints(
                "watch point",
                "preCICE watch points",
                np.array([point.coordinate[:2] for _, point in watch], dtype=float),
                tuple(
                    f"{owner}: {point.name}" if len(watch) > 1 else point.name
                    for owner, point in watch
                ),
            )
        )
    return sketch
