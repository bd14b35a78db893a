"""Load ``gymprecice-config.json``, validate it, and cross-check it with the preCICE XML.

Two forms are accepted. The Gym-preCICE paper's form (``solvers`` is a list of solver
directories driven by ``run``/``reset``/``prerun`` scripts) keeps working unchanged; the
explicit form names, per solver, the plugin ``kind`` that handles it and its options. Both
are validated with pydantic models that forbid unknown keys, and every error names the
file, the key, and what is allowed there. The cross-check then makes sure that what the JSON
asks of the controller exists in the preCICE configuration, naming both files, so a typo
fails at construction instead of hanging a coupled run.
"""

from __future__ import annotations

import difflib
import json
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal, get_args

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

from gymprecice.plugin.errors import ConfigError
from gymprecice.plugin.precice_xml import PreciceConfig, load_precice_config

if TYPE_CHECKING:  # imported when called: loading the config needs no numpy
    from gymprecice.plugin.solver import SolverContext

CONFIG_FILE_NAME = "gymprecice-config.json"
DEFAULT_LIBRARY = "precice"
DOUBLE_LIBRARY = "gymprecice.testing.fake_precice"


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid")


class EnvironmentSection(_Strict):
    name: str = "gymprecice"
    #: where each env's run directory ``env_<idx>`` is made (relative: to the working dir)
    run_root: str = "gymprecice-runs"
    #: reward of the step in which a solver diverged (None: the environment's own default,
    #: ``Adapter.divergence_penalty``); a finite number
    divergence_penalty: float | None = Field(default=None, allow_inf_nan=False, strict=True)


class SolverSection(_Strict):
    kind: str = "script"
    #: solver directory inside the case directory (default: the solver's name)
    path: str | None = None
    #: preCICE participant this solver plays (used for the cross-check and geometry)
    participant: str | None = None
    options: dict[str, Any] = Field(default_factory=dict)


class EngineSection(_Strict):
    solvers: list[str] | dict[str, SolverSection]
    reset_script: str | None = None
    run_script: str | None = None
    prerun_script: str | None = None


DataNames = str | list[str]


class ControllerSection(_Strict):
    participant: str = "Controller"
    read_from: dict[str, DataNames] = Field(default_factory=dict)
    write_to: dict[str, DataNames] = Field(default_factory=dict)
    #: interface name -> controller mesh name, where the names differ
    meshes: dict[str, str] = Field(default_factory=dict)
    #: interface name -> [xmin, xmax, ymin, ymax(, zmin, zmax)] for direct-access meshes
    access_regions: dict[str, list[float]] = Field(default_factory=dict)


class PreciceSection(_Strict):
    config_file: str = "precice-config.xml"
    #: module imported as ``precice`` by the coupling worker
    library: str = DEFAULT_LIBRARY


class ActionsSection(_Strict):
    #: preCICE time windows one env step spans
    windows: int = Field(default=1, ge=1)
    scheme: Literal["hold", "ramp", "cosine", "filter"] = "hold"
    #: exponential filter weight of the new action per window (scheme "filter")
    filter_alpha: float = Field(default=0.1, gt=0.0, le=1.0)


class TimeoutsSection(_Strict):
    #: seconds a reset may take (solver start, preCICE connection, initialisation)
    reset: float = Field(default=600.0, gt=0)
    #: seconds without any reply or solver-log growth before a solver counts as hung
    progress: float = Field(default=120.0, gt=0)
    #: hard cap on one step, whatever the progress (None: no cap)
    step: float | None = Field(default=None, gt=0)
    #: seconds solvers get to exit on their own at the end of an episode
    finalize: float = Field(default=30.0, ge=0)
    #: seconds between SIGTERM and SIGKILL when a process group is ended
    kill_grace: float = Field(default=2.0, ge=0)


class ConfigModel(_Strict):
    environment: EnvironmentSection = Field(default_factory=EnvironmentSection)
    physics_simulation_engine: EngineSection
    controller: ControllerSection = Field(default_factory=ControllerSection)
    precice: PreciceSection = Field(default_factory=PreciceSection)
    actions: ActionsSection = Field(default_factory=ActionsSection)
    timeouts: TimeoutsSection = Field(default_factory=TimeoutsSection)

    @field_validator("physics_simulation_engine")
    @classmethod
    def _some_solver(cls, value: EngineSection) -> EngineSection:
        if not value.solvers:
            raise ValueError("at least one solver is needed")
        return value


@dataclass
class SolverSpec:
    """One solver after the two config forms are unified."""

    name: str
    kind: str
    path: str
    participant: str | None
    options: dict[str, Any] = field(default_factory=dict)

    @property
    def cpus(self) -> int:
        """Processes the solver runs: its ``np`` option, 1 when unset (a serial run)."""
        return max(1, int(self.options.get("np", 1) or 1))


@dataclass(frozen=True)
class InterfaceSpec:
    """A controller interface: its mesh, the data written/read on it, who receives it."""

    name: str
    mesh: str
    write: tuple[str, ...]
    read: tuple[str, ...]
    dimensions: int
    #: the solver participant coupled to this mesh and that participant's own mesh
    partner: str | None = None
    partner_mesh: str | None = None
    #: a mesh received with api-access="true": its vertices come from the partner
    direct: bool = False


@dataclass
class GymPreciceConfig:
    """A validated, cross-checked configuration and where it came from."""

    file: Path | None
    case_dir: Path
    model: ConfigModel
    precice: PreciceConfig
    precice_file: Path
    solvers: dict[str, SolverSpec]
    interfaces: dict[str, InterfaceSpec]

    @property
    def controller(self) -> ControllerSection:
        return self.model.controller

    @property
    def participant(self) -> str:
        return self.model.controller.participant

    @property
    def end_time(self) -> float | None:
        return self.precice.end_time(self.participant)

    @property
    def time_window_size(self) -> float | None:
        return self.precice.time_window_size(self.participant)

    @property
    def precice_library(self) -> str:
        """The module the env imports as ``precice``: ``GYMPRECICE_PRECICE_LIBRARY``, else
        ``precice.library`` of the configuration."""
        from gymprecice.plugin.solver import LIBRARY_ENV_VAR

        return os.environ.get(LIBRARY_ENV_VAR) or self.model.precice.library

    @property
    def solver_cpus(self) -> int:
        """CPUs one env's solvers use at once: what a scheduler must reserve for it."""
        return sum(spec.cpus for spec in self.solvers.values())

    def where(self) -> str:
        return str(self.file) if self.file else f"<config dict for {self.case_dir}>"


def load_config(
    source: str | Path | Mapping[str, Any],
    *,
    case_dir: str | Path | None = None,
    validate_cases: bool = True,
) -> GymPreciceConfig:
    """Read and check a configuration.

    ``source`` is a path to ``gymprecice-config.json``, a case directory holding one, or an
    already parsed dict (then ``case_dir`` says where relative paths point; default: the
    working directory). Raises :class:`ConfigError` naming the file and key at fault.
    With ``validate_cases`` the installed plugins also check each solver's case files
    against the preCICE XML (see :func:`check_solver_cases`).
    """
    file: Path | None
    if isinstance(source, Mapping):
        raw = dict(source)
        file = None
        base = Path(case_dir or Path.cwd()).resolve()
    else:
        file = Path(source)
        if file.is_dir():
            file = file / CONFIG_FILE_NAME
        file = file.resolve()
        if not file.is_file():
            raise ConfigError(
                f"{file}: configuration file not found (expected {CONFIG_FILE_NAME} in the case directory)"
            )
        try:
            raw = json.loads(file.read_text())
        except json.JSONDecodeError as exc:
            raise ConfigError(
                f"{file}:{exc.lineno}:{exc.colno}: not valid JSON: {exc.msg}"
            ) from None
        base = Path(case_dir).resolve() if case_dir else file.parent
    where = str(file) if file else "<config dict>"
    try:
        model = ConfigModel.model_validate(raw)
    except ValidationError as exc:
        raise ConfigError(_explain(exc, where)) from None

    precice_file = (base / model.precice.config_file).resolve()
    if not precice_file.is_file():
        raise ConfigError(
            f"{where}: precice.config_file points at {precice_file}, which does not exist; "
            "set precice.config_file to the preCICE configuration relative to the case directory"
        )
    precice = load_precice_config(precice_file)
    solvers = _solvers(model, base, where)
    interfaces = _cross_check(model, precice, solvers, where)
    config = GymPreciceConfig(
        file=file,
        case_dir=base,
        model=model,
        precice=precice,
        precice_file=precice_file,
        solvers=solvers,
        interfaces=interfaces,
    )
    if validate_cases:
        check_solver_cases(config)
    return config


def pristine_context(config: GymPreciceConfig, name: str) -> SolverContext:
    """Solver ``name``'s context on the pristine case (no run directory yet): what its
    plugin checks (``gymprecice_validate_case``) and draws (``gymprecice_sketch_case``)."""
    from gymprecice.plugin.solver import SolverContext

    spec = config.solvers[name]
    source = config.case_dir / spec.path
    return SolverContext(
        name=spec.name,
        kind=spec.kind,
        run_dir=source,
        source_dir=source,
        env_dir=config.case_dir,
        participant=spec.participant,
        options=dict(spec.options),
        config_file=config.file,
        precice=config.precice,
        precice_config_file=config.precice_file,
        precice_library=config.precice_library,
    )


def check_solver_cases(config: GymPreciceConfig) -> None:
    """Ask each solver's plugin to check its pristine case against the preCICE XML.

    Plugins know their own files (a deal.II ``parameters.prm`` names its mesh and data);
    asking them here makes a mismatch fail at load time with every file named.
    """
    from gymprecice.plugin.manager import get_plugin_manager

    hook = get_plugin_manager().hook
    for spec in config.solvers.values():
        context = pristine_context(config, spec.name)
        problems = [
            p for answer in hook.gymprecice_validate_case(solver=context) for p in answer or ()
        ]
        if problems:
            # Only problems that name the preCICE file are disagreements with it; an
            # unknown option or a missing script is a problem of the case, said as such.
            about_precice = [p for p in problems if config.precice_file.name in p]
            if len(about_precice) == len(problems):
                what = f"does not agree with {config.precice_file}"
            else:
                what = "has problems in its case (each names the file at fault)"
            raise ConfigError(
                f"{config.where()}: solver {spec.name!r} ({spec.kind}) {what}:\n  "
                + "\n  ".join(problems)
            )


def check_solver_kinds(
    config: GymPreciceConfig, kinds: Mapping[str, Any], failures: Sequence[Any] = ()
) -> None:
    """Fail when a solver's ``kind`` has no installed plugin, saying what to install.

    ``failures`` are the installed plugins that could not be loaded
    (:func:`gymprecice.plugins.plugin_failures`): when there are any, the kind may well be
    one of theirs, and their import error, not ``pip install``, is what to fix.
    """
    for solver in config.solvers.values():
        if solver.kind in kinds:
            continue
        key = f"physics_simulation_engine.solvers.{solver.name}.kind"
        close = difflib.get_close_matches(solver.kind, list(kinds), n=1)
        if close:  # a typo of an installed kind, not a missing plugin
            fix = f"did you mean {close[0]!r}? Set {key} to {close[0]!r}."
        elif failures:
            broken = "; ".join(
                f"{f.name!r}"
                + (f" (from {f.distribution} {f.version})" if f.distribution else "")
                + f": {f.error}"
                for f in failures
            )
            fix = (
                f"An installed plugin that could not be loaded may handle it: {broken}. Fix "
                "that error (`gymprecice plugins` lists the failures) rather than installing "
                "anything."
            )
        else:
            fix = (
                f"Install the plugin (e.g. `pip install gymprecice-{solver.kind}`) or fix the kind."
            )
        raise ConfigError(
            f"{config.where()}: {key} is {solver.kind!r}, but no installed plugin handles it; "
            f"installed kinds: {sorted(kinds)}. {fix}"
        )


def _solvers(model: ConfigModel, base: Path, where: str) -> dict[str, SolverSpec]:
    engine = model.physics_simulation_engine
    specs: dict[str, SolverSpec] = {}
    if isinstance(engine.solvers, list):  # the paper's form: script-driven solver directories
        scripts = {
            key: value
            for key, value in (
                ("run_script", engine.run_script),
                ("reset_script", engine.reset_script),
                ("prerun_script", engine.prerun_script),
            )
            if value
        }
        if "run_script" not in scripts:
            raise ConfigError(
                f"{where}: physics_simulation_engine.run_script is missing; the list form of "
                "'solvers' runs each solver through a run script (or use the explicit form "
                "with a 'kind' per solver)"
            )
        for name in engine.solvers:
            specs[name] = SolverSpec(name, "script", name, None, dict(scripts))
    else:
        for name, section in engine.solvers.items():
            specs[name] = SolverSpec(
                name, section.kind, section.path or name, section.participant, dict(section.options)
            )
    for spec in specs.values():
        if not (base / spec.path).is_dir():
            raise ConfigError(
                f"{where}: solver {spec.name!r}: directory {base / spec.path} does not exist; "
                "set its 'path' to the solver's case directory, relative to "
                f"{base}"
            )
    return specs


def _as_tuple(value: DataNames) -> tuple[str, ...]:
    return (value,) if isinstance(value, str) else tuple(value)


def resolve_interface_mesh(
    interface: str, controller: ControllerSection, precice: PreciceConfig, where: str
) -> str:
    """Find the controller mesh behind an interface name (see docs: explicit, exact, token)."""
    participant = precice.participant(controller.participant)
    provided = [*participant.provided_meshes, *participant.api_access_meshes]
    if interface in controller.meshes:
        mesh = controller.meshes[interface]
        if mesh not in provided:
            raise ConfigError(
                f"{where}: controller.meshes.{interface} is {mesh!r}, but participant "
                f"{participant.name!r} in {precice.path} provides no such mesh; it provides {provided}"
            )
        return mesh
    if interface in provided:
        return interface
    token_matches = [m for m in provided if interface.lower() in m.lower().split("-")]
    if len(token_matches) == 1:
        return token_matches[0]
    if len(token_matches) > 1:
        raise ConfigError(
            f"{where}: interface {interface!r} matches several meshes of participant "
            f"{participant.name!r} in {precice.path}: {token_matches}; name the mesh in "
            f"controller.meshes.{interface}"
        )
    raise ConfigError(
        f"{where}: interface {interface!r} (controller.write_to/read_from) matches no mesh "
        f"provided by participant {participant.name!r} in {precice.path}; it provides "
        f"{provided}. Rename the interface or map it in controller.meshes."
    )


def _cross_check(
    model: ConfigModel, precice: PreciceConfig, solvers: dict[str, SolverSpec], where: str
) -> dict[str, InterfaceSpec]:
    controller = model.controller
    if controller.participant not in precice.participants:
        raise ConfigError(
            f"{where}: controller.participant is {controller.participant!r}, but "
            f"{precice.path} has no such participant; its participants are "
            f"{sorted(precice.participants)}"
        )
    for solver in solvers.values():
        if solver.participant and solver.participant not in precice.participants:
            raise ConfigError(
                f"{where}: physics_simulation_engine.solvers.{solver.name}.participant is "
                f"{solver.participant!r}, but {precice.path} has no such participant; its "
                f"participants are {sorted(precice.participants)}"
            )
    me = precice.participant(controller.participant)
    names = list(dict.fromkeys([*controller.write_to, *controller.read_from]))
    interfaces: dict[str, InterfaceSpec] = {}
    for name in names:
        mesh = resolve_interface_mesh(name, controller, precice, where)
        write = _as_tuple(controller.write_to.get(name, ()))
        read = _as_tuple(controller.read_from.get(name, ()))
        for data in write:
            if (data, mesh) not in me.write_data:
                raise ConfigError(
                    f"{where}: controller.write_to.{name} asks to write {data!r} on mesh "
                    f"{mesh!r}, but in {precice.path} participant {me.name!r} writes "
                    f"{_pairs(me.write_data, mesh)} on that mesh; add "
                    f'<write-data name="{data}" mesh="{mesh}"/> there or fix the JSON'
                )
        for data in read:
            if (data, mesh) not in me.read_data:
                raise ConfigError(
                    f"{where}: controller.read_from.{name} asks to read {data!r} on mesh "
                    f"{mesh!r}, but in {precice.path} participant {me.name!r} reads "
                    f"{_pairs(me.read_data, mesh)} on that mesh; add "
                    f'<read-data name="{data}" mesh="{mesh}"/> there or fix the JSON'
                )
        direct = mesh in me.api_access_meshes
        partner = (me.received_meshes[mesh], mesh) if direct else precice.mapped_partner_mesh(mesh)
        interfaces[name] = InterfaceSpec(
            name=name,
            mesh=mesh,
            write=write,
            read=read,
            dimensions=precice.mesh(mesh).dimensions,
            partner=partner[0] if partner else None,
            partner_mesh=partner[1] if partner else None,
            direct=direct,
        )
    if not interfaces:
        raise ConfigError(
            f"{where}: controller.write_to and controller.read_from are both empty; name at "
            "least one interface the controller writes to or reads from"
        )
    return interfaces


def _pairs(pairs: list[tuple[str, str]], mesh: str) -> list[str]:
    return [data for data, m in pairs if m == mesh] or ["nothing"]


def _models_in(annotation: Any) -> list[type[BaseModel]]:
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return [annotation]
    return [model for arg in get_args(annotation) for model in _models_in(arg)]


def _allowed_keys(loc: tuple[Any, ...]) -> list[str] | None:
    """Field names allowed where ``loc`` points (for 'unknown key' messages)."""
    model: type[BaseModel] = ConfigModel
    for part in loc[:-1]:
        info = model.model_fields.get(str(part))
        if info is None:  # a dict key or a union tag: same model
            continue
        inner = _models_in(info.annotation)
        if not inner:
            return None
        model = inner[0]
    return sorted(model.model_fields)


def _explain(exc: ValidationError, where: str) -> str:
    lines = []
    for error in exc.errors():
        loc = tuple(error["loc"])
        key = ".".join(
            str(p) for p in loc if not (isinstance(p, str) and p.startswith(("list[", "dict[")))
        )
        if error["type"] == "extra_forbidden":
            allowed = _allowed_keys(loc)
            hint = f"; allowed keys here: {', '.join(allowed)}" if allowed else ""
            lines.append(f"unknown key {key!r}{hint}")
        elif error["type"] == "missing":
            lines.append(f"missing key {key!r}")
        else:
            lines.append(f"{key}: {error['msg']} (got {error.get('input')!r})")
    unique = list(dict.fromkeys(lines))
    return f"{where}: invalid gymprecice configuration:\n  " + "\n  ".join(unique)
