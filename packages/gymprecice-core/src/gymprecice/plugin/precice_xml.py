"""Read a preCICE v3 configuration file into plain data.

preCICE writes its tags with prefixes (``<data:vector>``, ``<coupling-scheme:multi>``) that
no namespace declaration binds, so a strict XML parser refuses the file. lxml parses it in
recovery mode; we then accept *only* the namespace complaints and turn every other parser
error into a :class:`~gymprecice.errors.ConfigError` naming the file and line. The result
is a small, typed picture of what gymprecice needs: participants with their meshes and
data, meshes with dimensions, data types, coupling schemes with their times, and m2n
connections (whose exchange directories each env rewrites in its own copy).
"""

from __future__ import annotations

import xml.parsers.expat
from dataclasses import dataclass, field
from pathlib import Path

from lxml import etree

from gymprecice.plugin.errors import ConfigError


@dataclass(frozen=True)
class DataSpec:
    name: str
    kind: str  # "scalar" or "vector"
    waveform_degree: int | None = None


@dataclass
class MeshSpec:
    name: str
    dimensions: int
    data: list[str] = field(default_factory=list)


@dataclass(frozen=True)
class MappingSpec:
    method: str  # e.g. "nearest-neighbor", "rbf-pum-direct"
    direction: str  # "read" or "write"
    from_mesh: str
    to_mesh: str
    constraint: str = "consistent"


@dataclass(frozen=True)
class WatchPointSpec:
    name: str
    mesh: str
    coordinate: tuple[float, ...]


@dataclass
class ParticipantSpec:
    name: str
    provided_meshes: list[str] = field(default_factory=list)
    #: received mesh name -> participant it comes from
    received_meshes: dict[str, str] = field(default_factory=dict)
    #: mesh names received with api-access="true" (direct access, no mapping)
    api_access_meshes: list[str] = field(default_factory=list)
    #: (data, mesh) pairs
    write_data: list[tuple[str, str]] = field(default_factory=list)
    read_data: list[tuple[str, str]] = field(default_factory=list)
    mappings: list[MappingSpec] = field(default_factory=list)
    watch_points: list[WatchPointSpec] = field(default_factory=list)

    @property
    def meshes(self) -> list[str]:
        return [*self.provided_meshes, *self.received_meshes]


@dataclass(frozen=True)
class ExchangeSpec:
    data: str
    mesh: str
    from_participant: str
    to_participant: str
    initialize: bool = False


@dataclass
class CouplingSchemeSpec:
    kind: str  # "parallel-explicit", "serial-implicit", "multi", ...
    participants: list[str]
    first: str | None = None
    second: str | None = None
    control: str | None = None  # multi coupling's controlling participant
    max_time: float | None = None
    max_time_windows: int | None = None
    time_window_size: float | None = None  # None with method="first-participant"
    time_window_method: str = "fixed"
    max_iterations: int | None = None
    exchanges: list[ExchangeSpec] = field(default_factory=list)
    #: for "multi": the two-participant schemes are unknown; exchanges carry the pairs
    line: int | None = None

    @property
    def implicit(self) -> bool:
        return self.kind.endswith("implicit") or self.kind == "multi"

    @property
    def serial(self) -> bool:
        return self.kind.startswith("serial")


@dataclass(frozen=True)
class M2NSpec:
    kind: str  # "sockets", "mpi", "mpi-multiple-ports"
    acceptor: str
    connector: str
    exchange_directory: str = ""


@dataclass
class PreciceConfig:
    """The parts of a preCICE v3 configuration that gymprecice uses."""

    path: Path
    data: dict[str, DataSpec] = field(default_factory=dict)
    meshes: dict[str, MeshSpec] = field(default_factory=dict)
    participants: dict[str, ParticipantSpec] = field(default_factory=dict)
    coupling_schemes: list[CouplingSchemeSpec] = field(default_factory=list)
    m2n: list[M2NSpec] = field(default_factory=list)

    def participant(self, name: str) -> ParticipantSpec:
        try:
            return self.participants[name]
        except KeyError:
            raise ConfigError(
                f"{self.path}: no participant named {name!r}; "
                f"the participants are {sorted(self.participants)}"
            ) from None

    def mesh(self, name: str) -> MeshSpec:
        try:
            return self.meshes[name]
        except KeyError:
            raise ConfigError(
                f"{self.path}: no mesh named {name!r}; the meshes are {sorted(self.meshes)}"
            ) from None

    def schemes_of(self, participant: str) -> list[CouplingSchemeSpec]:
        return [s for s in self.coupling_schemes if participant in s.participants]

    def end_time(self, participant: str) -> float | None:
        """Simulation end time seen by ``participant`` (``max-time`` or windows x size)."""
        for scheme in self.schemes_of(participant):
            if scheme.max_time is not None:
                return scheme.max_time
            if scheme.max_time_windows is not None and scheme.time_window_size:
                return scheme.max_time_windows * scheme.time_window_size
        return None

    def time_window_size(self, participant: str) -> float | None:
        for scheme in self.schemes_of(participant):
            if scheme.time_window_size:
                return scheme.time_window_size
        return None

    def data_dimension(self, data: str, mesh: str) -> int:
        """Components per vertex: 1 for scalar data, the mesh dimension for vector data."""
        spec = self.data.get(data)
        if spec is None:
            raise ConfigError(
                f"{self.path}: no data named {data!r}; the data are {sorted(self.data)}"
            )
        return 1 if spec.kind == "scalar" else self.mesh(mesh).dimensions

    def provider_of(self, mesh: str) -> str | None:
        """The participant that provides ``mesh`` (``<provide-mesh>``), if any."""
        for participant in self.participants.values():
            if mesh in participant.provided_meshes:
                return participant.name
        return None

    def mapped_partner_mesh(self, mesh: str) -> tuple[str, str] | None:
        """For a mesh provided by one participant, the (participant, own mesh) mapped to it.

        The controller provides an interface mesh; the solver participant that receives it
        maps between it and one of its own meshes. That own mesh is what a solver plugin
        knows (e.g. the OpenFOAM adapter's interface in ``preciceDict``).

        The mesh's provider is never its own partner: a controller with a read mapping of
        its own (``from="Fluid-Mesh" to="Controller-Mesh"``, common in preCICE) names the
        *other* mesh, and the partner is whoever provides that one.
        """
        owner = self.provider_of(mesh)
        for participant in self.participants.values():
            if participant.name == owner:
                continue
            for mapping in participant.mappings:
                if mapping.from_mesh == mesh:
                    return participant.name, mapping.to_mesh
                if mapping.to_mesh == mesh:
                    return participant.name, mapping.from_mesh
        if owner is not None:
            for mapping in self.participants[owner].mappings:
                other = {mapping.from_mesh, mapping.to_mesh} - {mesh}
                if mesh not in (mapping.from_mesh, mapping.to_mesh) or len(other) != 1:
                    continue
                (other_mesh,) = other
                partner = self.provider_of(other_mesh)
                if partner is not None and partner != owner:
                    return partner, other_mesh
        for participant in self.participants.values():
            if participant.name != owner and mesh in participant.received_meshes:
                return participant.name, mesh
        return None


def _float(elem: etree._Element, attr: str, path: Path) -> float:
    raw = elem.get(attr)
    try:
        return float(raw)
    except (TypeError, ValueError):
        raise ConfigError(
            f"{path}:{elem.sourceline}: <{elem.tag}> needs a number in {attr}=, got {raw!r}"
        ) from None


def _required(elem: etree._Element, attr: str, path: Path) -> str:
    value = elem.get(attr)
    if value is None:
        raise ConfigError(f"{path}:{elem.sourceline}: <{elem.tag}> lacks the attribute {attr}=")
    return value


def _is_true(value: str | None) -> bool:
    return (value or "").strip().lower() in ("1", "yes", "true", "on")


def parse_tree(path: Path, *, keep_comments: bool = False) -> etree._ElementTree:
    """Parse the XML, tolerating only preCICE's unbound tag prefixes."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"{path}: preCICE configuration file not found")
    _check_well_formed(path)
    parser = etree.XMLParser(recover=True, remove_comments=not keep_comments)
    tree = etree.parse(str(path), parser)
    fatal = [e for e in parser.error_log if e.domain_name != "NAMESPACE"]
    if fatal or tree.getroot() is None:
        first = fatal[0] if fatal else None
        where = f"{path}:{first.line}" if first else str(path)
        raise ConfigError(f"{where}: not well-formed XML: {first.message if first else 'empty'}")
    return tree


def _check_well_formed(path: Path) -> None:
    """Refuse what preCICE's own parser refuses, such as junk after the root element.

    lxml in recovery mode silently stops at the end of the root element, so ``<oops``
    appended to a file would pass, and the per-env copy (re-serialised) would even run,
    while preCICE rejects the original. Expat without namespace processing reads
    ``data:vector`` as a plain tag name, so it checks well-formedness and nothing else.
    """
    parser = xml.parsers.expat.ParserCreate()
    try:
        parser.Parse(path.read_bytes(), True)
    except xml.parsers.expat.ExpatError as exc:
        reason = xml.parsers.expat.errors.messages[exc.code] if exc.code else str(exc)
        fix = "fix the XML at that line"
        if reason == xml.parsers.expat.errors.XML_ERROR_JUNK_AFTER_DOC_ELEMENT:
            fix = "delete what follows </precice-configuration> (only comments may)"
        raise ConfigError(
            f"{path}:{exc.lineno}:{exc.offset + 1}: not well-formed XML: {reason}; preCICE "
            f"refuses this file too: {fix}"
        ) from None


def load_precice_config(path: str | Path) -> PreciceConfig:
    """Read ``path`` (a preCICE v3 ``precice-config.xml``)."""
    path = Path(path)
    root = parse_tree(path).getroot()
    if root.tag != "precice-configuration":
        raise ConfigError(f"{path}: the root element must be <precice-configuration>")
    if root.find("solver-interface") is not None:
        raise ConfigError(
            f"{path}: this is a preCICE v2 configuration (<solver-interface>); gymprecice "
            "needs preCICE v3. Convert it with preCICE's config transformer "
            "(precice-config-transformer) and check the result."
        )
    cfg = PreciceConfig(path=path)
    for elem in root:
        if not isinstance(elem.tag, str):
            continue
        tag = elem.tag
        if tag.startswith("data:"):
            name = _required(elem, "name", path)
            degree = elem.get("waveform-degree")
            cfg.data[name] = DataSpec(name, tag.split(":", 1)[1], int(degree) if degree else None)
        elif tag == "mesh":
            name = _required(elem, "name", path)
            dims = elem.get("dimensions")
            if dims is None:
                raise ConfigError(
                    f"{path}:{elem.sourceline}: <mesh name={name!r}> lacks dimensions= "
                    "(preCICE v3 sets the dimension per mesh)"
                )
            uses = [_required(u, "name", path) for u in elem.findall("use-data")]
            cfg.meshes[name] = MeshSpec(name, int(dims), uses)
        elif tag == "participant":
            cfg.participants[_required(elem, "name", path)] = _participant(elem, path)
        elif tag.startswith("m2n:"):
            cfg.m2n.append(
                M2NSpec(
                    kind=tag.split(":", 1)[1],
                    acceptor=elem.get("acceptor") or elem.get("from") or "",
                    connector=elem.get("connector") or elem.get("to") or "",
                    exchange_directory=elem.get("exchange-directory", ""),
                )
            )
        elif tag.startswith("coupling-scheme:"):
            cfg.coupling_schemes.append(_scheme(elem, path))
    _check_references(cfg)
    return cfg


def _participant(elem: etree._Element, path: Path) -> ParticipantSpec:
    spec = ParticipantSpec(name=elem.get("name"))
    for child in elem:
        if not isinstance(child.tag, str):
            continue
        tag = child.tag
        if tag == "provide-mesh":
            spec.provided_meshes.append(_required(child, "name", path))
        elif tag == "receive-mesh":
            name = _required(child, "name", path)
            spec.received_meshes[name] = _required(child, "from", path)
            if _is_true(child.get("api-access")) or _is_true(child.get("direct-access")):
                spec.api_access_meshes.append(name)
        elif tag == "write-data":
            spec.write_data.append((_required(child, "name", path), _required(child, "mesh", path)))
        elif tag == "read-data":
            spec.read_data.append((_required(child, "name", path), _required(child, "mesh", path)))
        elif tag.startswith("mapping:"):
            spec.mappings.append(
                MappingSpec(
                    method=tag.split(":", 1)[1],
                    direction=_required(child, "direction", path),
                    from_mesh=_required(child, "from", path),
                    to_mesh=_required(child, "to", path),
                    constraint=child.get("constraint", "consistent"),
                )
            )
        elif tag == "watch-point":
            coords = tuple(float(x) for x in _required(child, "coordinate", path).split(";"))
            spec.watch_points.append(
                WatchPointSpec(
                    _required(child, "name", path), _required(child, "mesh", path), coords
                )
            )
        elif tag == "use-mesh":
            raise ConfigError(
                f"{path}:{child.sourceline}: <use-mesh> is preCICE v2 syntax; preCICE v3 uses "
                "<provide-mesh> and <receive-mesh from=...>"
            )
    return spec


def _scheme(elem: etree._Element, path: Path) -> CouplingSchemeSpec:
    kind = elem.tag.split(":", 1)[1]
    scheme = CouplingSchemeSpec(kind=kind, participants=[], line=elem.sourceline)
    for child in elem:
        if not isinstance(child.tag, str):
            continue
        tag = child.tag
        if tag == "participants":
            scheme.first = _required(child, "first", path)
            scheme.second = _required(child, "second", path)
            scheme.participants = [scheme.first, scheme.second]
        elif tag == "participant":  # multi coupling
            name = _required(child, "name", path)
            scheme.participants.append(name)
            if _is_true(child.get("control")):
                scheme.control = name
        elif tag == "max-time":
            scheme.max_time = _float(child, "value", path)
        elif tag == "max-time-windows":
            scheme.max_time_windows = int(_float(child, "value", path))
        elif tag == "time-window-size":
            scheme.time_window_method = child.get("method", "fixed")
            if child.get("value") is not None:
                scheme.time_window_size = _float(child, "value", path)
        elif tag == "max-iterations":
            scheme.max_iterations = int(_float(child, "value", path))
        elif tag == "exchange":
            scheme.exchanges.append(
                ExchangeSpec(
                    data=_required(child, "data", path),
                    mesh=_required(child, "mesh", path),
                    from_participant=_required(child, "from", path),
                    to_participant=_required(child, "to", path),
                    initialize=_is_true(child.get("initialize")),
                )
            )
    return scheme


def _check_references(cfg: PreciceConfig) -> None:
    """Catch the dangling names preCICE would only report at run time, with the file."""
    where = cfg.path
    for mesh in cfg.meshes.values():
        for data in mesh.data:
            if data not in cfg.data:
                raise ConfigError(f"{where}: mesh {mesh.name!r} uses unknown data {data!r}")
    for participant in cfg.participants.values():
        for mesh in participant.meshes:
            if mesh not in cfg.meshes:
                raise ConfigError(
                    f"{where}: participant {participant.name!r} uses unknown mesh {mesh!r}"
                )
        for data, mesh in [*participant.write_data, *participant.read_data]:
            if data not in cfg.data:
                raise ConfigError(
                    f"{where}: participant {participant.name!r} exchanges unknown data {data!r}"
                )
            if mesh in cfg.meshes and data not in cfg.meshes[mesh].data:
                raise ConfigError(
                    f"{where}: participant {participant.name!r} reads/writes {data!r} on mesh "
                    f"{mesh!r}, which does not <use-data name={data!r}/>"
                )
    for scheme in cfg.coupling_schemes:
        for name in scheme.participants:
            if name not in cfg.participants:
                raise ConfigError(
                    f"{where}:{scheme.line}: coupling scheme {scheme.kind} names unknown "
                    f"participant {name!r}"
                )


def write_with_exchange_directory(source: Path, target: Path, exchange_directory: Path) -> None:
    """Copy a preCICE configuration, pointing every m2n at ``exchange_directory``.

    Each env gets its own exchange directory, so N envs can run side by side without
    their socket address files colliding. Only the ``exchange-directory`` attributes change;
    everything else, comments included, is kept.
    """
    tree = parse_tree(source, keep_comments=True)
    for elem in tree.getroot():
        if isinstance(elem.tag, str) and elem.tag.startswith("m2n:"):
            elem.set("exchange-directory", str(exchange_directory))
    target.write_bytes(etree.tostring(tree, xml_declaration=True, encoding="UTF-8"))
