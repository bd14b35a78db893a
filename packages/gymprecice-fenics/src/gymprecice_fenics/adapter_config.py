"""fenicsprecice's ``precice-adapter-config.json``: read it, point it, check it.

fenicsprecice 2.x couples one participant through one mesh with at most one read and one
write data name, all taken from this file (``participant_name``, ``config_file_name``
relative to the file, ``interface.coupling_mesh_name``, ``interface.read_data_name``,
``interface.write_data_name``). A name that disagrees with the preCICE XML stops the
participant at run time with a preCICE error that does not say which file is wrong; here it
is reported before anything starts, naming both files.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path

from gymprecice.plugin import CaseError, PreciceConfig

__all__ = ["AdapterConfig", "check_against_precice"]


@dataclass
class AdapterConfig:
    """The parts of ``precice-adapter-config.json`` gymprecice checks or changes."""

    path: Path
    raw: dict
    participant: str
    config_file_name: str
    mesh: str
    read_data: str | None
    write_data: str | None

    @classmethod
    def read(cls, path: Path) -> AdapterConfig:
        try:
            raw = json.loads(path.read_text())
        except FileNotFoundError:
            raise CaseError(
                f"{path} does not exist; fenicsprecice reads the participant, mesh and data "
                "names from it (copy the case's precice-adapter-config.json into the solver "
                "directory, or set options.adapter_config)"
            ) from None
        except (OSError, ValueError) as exc:
            raise CaseError(f"{path}: not valid JSON ({exc}); fix the file") from None
        interface = raw.get("interface") if isinstance(raw, dict) else None
        missing = [
            key
            for key, value in (
                (
                    "participant_name",
                    raw.get("participant_name") if isinstance(raw, dict) else None,
                ),
                (
                    "config_file_name",
                    raw.get("config_file_name") if isinstance(raw, dict) else None,
                ),
                (
                    "interface.coupling_mesh_name",
                    interface.get("coupling_mesh_name") if isinstance(interface, dict) else None,
                ),
            )
            if not isinstance(value, str) or not value
        ]
        if missing:
            raise CaseError(f"{path}: fenicsprecice needs {missing}, which this file does not set")
        assert isinstance(interface, dict)
        read, write = interface.get("read_data_name"), interface.get("write_data_name")
        if read is None and write is None:
            raise CaseError(
                f"{path}: the interface has neither read_data_name nor write_data_name; a "
                "coupled FEniCS participant reads or writes at least one"
            )
        return cls(
            path=path,
            raw=raw,
            participant=raw["participant_name"],
            config_file_name=raw["config_file_name"],
            mesh=interface["coupling_mesh_name"],
            read_data=read,
            write_data=write,
        )

    def point_at(self, precice_config_file: Path) -> bool:
        """Make ``config_file_name`` name ``precice_config_file`` (relative to this file,
        as fenicsprecice resolves it); returns whether the file changed."""
        target = os.path.relpath(Path(precice_config_file).resolve(), self.path.parent.resolve())
        if target == self.config_file_name:
            return False
        self.raw["config_file_name"] = target
        self.config_file_name = target
        self.path.write_text(json.dumps(self.raw, indent=2) + "\n")
        return True


def check_against_precice(
    adapter: AdapterConfig, cfg: PreciceConfig, solver_participant: str | None, where: str
) -> list[str]:
    """Every disagreement between the adapter file and the preCICE XML, each with its fix.

    Besides the names, a datum the participant reads must be written to its mesh by
    someone: a controller writing ``Heat-Flux`` where the FEniCS script reads
    ``Temperature`` shows up here, naming the writer.
    """
    file, xml = adapter.path, cfg.path
    participant = adapter.participant
    if solver_participant and solver_participant != participant:
        return [
            f"{file}: participant_name is {participant!r}, but {where} says this solver is "
            f"participant {solver_participant!r}; make them equal"
        ]
    if participant not in cfg.participants:
        return [
            f"{file}: participant_name is {participant!r}, but {xml} has no such participant; "
            f"its participants are {sorted(cfg.participants)}"
        ]
    spec = cfg.participants[participant]
    if adapter.mesh not in spec.provided_meshes:
        return [
            f"{file}: interface.coupling_mesh_name is {adapter.mesh!r}, but in {xml} participant "
            f"{participant!r} provides {spec.provided_meshes}; make the mesh names agree"
        ]
    problems = []
    for key, data, pairs, tag in (
        ("read_data_name", adapter.read_data, spec.read_data, "read-data"),
        ("write_data_name", adapter.write_data, spec.write_data, "write-data"),
    ):
        on_mesh = [d for d, m in pairs if m == adapter.mesh]
        if data is None:
            if on_mesh:
                problems.append(
                    f"{file}: interface.{key} is not set, but in {xml} participant "
                    f"{participant!r} has <{tag}> {on_mesh} on mesh {adapter.mesh!r}; set it"
                )
            continue
        if data not in on_mesh:
            problems.append(
                f"{file}: interface.{key} is {data!r}, but in {xml} participant {participant!r} "
                f"has <{tag}> {on_mesh} on mesh {adapter.mesh!r}; make the data names agree"
            )
    if not problems:
        problems += _check_writers(adapter, cfg)
    return problems


def _check_writers(adapter: AdapterConfig, cfg: PreciceConfig) -> list[str]:
    """What the participant reads on each of its meshes must be sent to that mesh.

    A datum arrives on a mesh either exchanged on it, or exchanged on a partner's mesh that
    the participant maps to it. Checked for every ``<read-data>`` of the participant: the
    adapter file's mesh and any second mesh the script reads through the adapter's
    participant (a heater the controller drives).
    """
    spec = cfg.participants[adapter.participant]
    sources: dict[str, set[str]] = {}
    for mapping in spec.mappings:
        if mapping.direction == "read":
            sources.setdefault(mapping.to_mesh, set()).add(mapping.from_mesh)
    incoming = [
        (ex.data, ex.mesh, ex.from_participant)
        for scheme in cfg.coupling_schemes
        for ex in scheme.exchanges
        if ex.to_participant == adapter.participant
    ]
    problems = []
    for data, mesh in spec.read_data:
        meshes = {mesh, *sources.get(mesh, ())}
        arriving = [(d, who) for d, m, who in incoming if m in meshes]
        if not arriving or any(d == data for d, _ in arriving):
            continue
        sent = ", ".join(f"{d!r} from {who!r}" for d, who in arriving)
        where = (
            "the script"
            if mesh == adapter.mesh
            else "the script (through the adapter's participant)"
        )
        problems.append(
            f"{adapter.path}: {where} of FEniCS participant {adapter.participant!r} reads "
            f"{data!r} on mesh {mesh!r}, but {cfg.path} exchanges only {sent} to it; make "
            f"the writer write {data!r} (or the script read what is sent)"
        )
    return problems
