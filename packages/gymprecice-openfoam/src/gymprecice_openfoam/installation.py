"""Find the OpenFOAM installation and the environment its programs need.

OpenFOAM programs refuse to start without ``WM_PROJECT_DIR`` (they look up
``$WM_PROJECT_DIR/etc/controlDict``), and installations differ in how that gets set:

* a sourced installation (``source <install>/etc/bashrc``) already exports it;
* the Debian/Ubuntu ``openfoam`` package puts the programs in ``/usr/bin`` and the
  ``etc`` directory in ``/usr/share/openfoam``, but its ``etc/bashrc`` cannot be sourced
  (it calls helper scripts the package does not ship). Setting
  ``WM_PROJECT_DIR=/usr/share/openfoam`` is all the programs need;
* the ESI packages (``/usr/lib/openfoam/openfoamXXXX``) and source builds under ``/opt``
  are not on ``PATH`` until their ``etc/bashrc`` is sourced; we source it once in a
  child shell and keep the resulting environment.

Everything here is read-only: the result is a mapping of variables that the plugin adds
to the environment of the processes it starts.
"""

from __future__ import annotations

import functools
import glob
import os
import shutil
import subprocess
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from gymprecice.plugin import CaseError, solver_environment

#: Environment variable naming an OpenFOAM ``etc/bashrc`` to source (overrides discovery).
BASHRC_ENV = "GYMPRECICE_OPENFOAM_BASHRC"

#: Where packaged OpenFOAM installations put their ``etc/bashrc`` when not on PATH.
_BASHRC_GLOBS = (
    "/usr/lib/openfoam/openfoam*/etc/bashrc",
    "/opt/openfoam*/etc/bashrc",
    "/opt/OpenFOAM-*/etc/bashrc",
    "/opt/OpenFOAM/OpenFOAM-*/etc/bashrc",
)

#: Library of the OpenFOAM-preCICE adapter (a function object loaded through controlDict).
ADAPTER_LIBRARY = "libpreciceAdapterFunctionObject.so"


@dataclass(frozen=True)
class OpenFOAMInstallation:
    """One usable OpenFOAM installation.

    ``env`` holds the variables to add to a process environment so that OpenFOAM
    programs start (at least ``WM_PROJECT_DIR``; ``PATH`` and ``LD_LIBRARY_PATH`` too when
    they come from a sourced ``bashrc``).
    """

    project_dir: Path
    layout: str  # "sourced", "debian", "bin-on-path" or "bashrc"
    env: Mapping[str, str] = field(default_factory=dict)
    version: str | None = None

    def environ(self, base: Mapping[str, str] | None = None) -> dict[str, str]:
        """A full environment: ``base`` (default ``os.environ``) with ``env`` applied.

        The stack built by ``gymprecice install`` is added last (its ``lib`` on
        ``LD_LIBRARY_PATH``): OpenFOAM ``dlopen``s the preCICE adapter by bare name.
        """
        merged = dict(os.environ if base is None else base)
        merged.update(self.env)
        merged.update(solver_environment(merged))
        return merged

    def which(self, program: str) -> str | None:
        """Path of ``program`` as the OpenFOAM environment would find it.

        The directory is resolved (``/bin`` is often a link to ``/usr/bin``): Open MPI
        derives its prefix from where ``mpirun`` was started and fails for ``/bin``.
        """
        return _which(program, self.environ().get("PATH", os.defpath))

    def library_dirs(self) -> list[Path]:
        """Directories searched for function-object libraries (user, site, project, system)."""
        env = self.environ()
        dirs: list[Path] = []
        for key in ("FOAM_USER_LIBBIN", "FOAM_SITE_LIBBIN", "FOAM_LIBBIN"):
            if env.get(key):
                dirs.append(Path(env[key]))
        for item in env.get("LD_LIBRARY_PATH", "").split(os.pathsep):
            if item:
                dirs.append(Path(item))
        dirs += [Path("/usr/lib"), Path("/usr/local/lib"), Path("/usr/lib/x86_64-linux-gnu")]
        seen: set[Path] = set()
        return [d for d in dirs if not (d in seen or seen.add(d))]

    def find_library(self, name: str = ADAPTER_LIBRARY) -> Path | None:
        """Where ``name`` is, or ``None`` (used for the preCICE adapter check)."""
        for directory in self.library_dirs():
            candidate = directory / name
            if candidate.is_file():
                return candidate
        return None


def _which(program: str, path: str) -> str | None:
    found = shutil.which(program, path=path)
    if found is None:
        return None
    return os.path.join(os.path.realpath(os.path.dirname(found)), os.path.basename(found))


def _has_etc(directory: Path) -> bool:
    return (directory / "etc" / "controlDict").is_file()


def _project_dir_for_binary(binary: Path) -> tuple[Path, str] | None:
    """Guess ``WM_PROJECT_DIR`` from where an OpenFOAM program lives."""
    real = binary.resolve()
    bin_dir = real.parent
    prefix = bin_dir.parent
    candidates = [
        (prefix / "share" / "openfoam", "debian"),  # Debian: /usr/bin + /usr/share/openfoam
        (prefix, "bin-on-path"),  # <project>/bin
        # <project>/platforms/<arch>/bin
        (bin_dir.parent.parent.parent, "bin-on-path"),
    ]
    for directory, layout in candidates:
        if _has_etc(directory):
            return directory, layout
    return None


def _version_of(project_dir: Path, env: Mapping[str, str]) -> str | None:
    if env.get("WM_PROJECT_VERSION"):
        return env["WM_PROJECT_VERSION"]
    bashrc = project_dir / "etc" / "bashrc"
    try:
        for line in bashrc.read_text(errors="replace").splitlines():
            line = line.strip()
            if line.startswith("export WM_PROJECT_VERSION="):
                return line.split("=", 1)[1].strip() or None
    except OSError:
        return None
    return None


@functools.lru_cache(maxsize=8)
def _source_bashrc(bashrc: str) -> tuple[tuple[str, str], ...]:
    """Environment after ``source bashrc`` in a clean child bash (cached per file)."""
    try:
        out = subprocess.run(
            ["bash", "-c", 'source "$0" >/dev/null 2>&1; env -0', bashrc],
            capture_output=True,
            timeout=60,
            check=False,
            env={k: v for k, v in os.environ.items() if not k.startswith(("WM_", "FOAM_"))},
        ).stdout
    except (OSError, subprocess.TimeoutExpired):
        return ()
    pairs = []
    for item in out.split(b"\0"):
        if b"=" in item:
            key, value = item.split(b"=", 1)
            pairs.append((key.decode(errors="replace"), value.decode(errors="replace")))
    return tuple(pairs)


def _from_bashrc(bashrc: Path) -> OpenFOAMInstallation | None:
    sourced = dict(_source_bashrc(str(bashrc)))
    project = sourced.get("WM_PROJECT_DIR")
    if not project or not _has_etc(Path(project)):
        return None
    keep = {
        k: v
        for k, v in sourced.items()
        if k.startswith(("WM_", "FOAM_", "MPI_"))
        or k in ("PATH", "LD_LIBRARY_PATH", "WM_PROJECT_DIR", "OPAL_PREFIX")
    }
    return OpenFOAMInstallation(
        project_dir=Path(project),
        layout="bashrc",
        env=keep,
        version=_version_of(Path(project), sourced),
    )


def find_openfoam(
    environ: Mapping[str, str] | None = None, *, bashrc: str | os.PathLike[str] | None = None
) -> OpenFOAMInstallation:
    """Locate OpenFOAM, or raise :class:`CaseError` saying how to make it available.

    Order: an explicit ``bashrc`` (argument or ``$GYMPRECICE_OPENFOAM_BASHRC``), an already
    sourced environment (``WM_PROJECT_DIR``), programs on ``PATH`` (Debian layout or a
    project's ``bin``), then the usual packaged locations' ``etc/bashrc``.
    """
    env = dict(os.environ if environ is None else environ)
    explicit = bashrc or env.get(BASHRC_ENV)
    if explicit:
        found = _from_bashrc(Path(explicit))
        if found is None:
            raise CaseError(
                f"OpenFOAM: sourcing {explicit} did not give a usable WM_PROJECT_DIR "
                f"(no etc/controlDict there); point {BASHRC_ENV} at <install>/etc/bashrc"
            )
        return found

    project = env.get("WM_PROJECT_DIR")
    if project and _has_etc(Path(project)):
        return OpenFOAMInstallation(
            project_dir=Path(project),
            layout="sourced",
            env={"WM_PROJECT_DIR": project},
            version=_version_of(Path(project), env),
        )

    path = env.get("PATH", os.defpath)
    for program in ("blockMesh", "foamDictionary", "simpleFoam", "icoFoam"):
        binary = shutil.which(program, path=path)
        if binary:
            guess = _project_dir_for_binary(Path(binary))
            if guess is not None:
                directory, layout = guess
                return OpenFOAMInstallation(
                    project_dir=directory,
                    layout=layout,
                    env={"WM_PROJECT_DIR": str(directory)},
                    version=_version_of(directory, env),
                )

    for pattern in _BASHRC_GLOBS:
        for candidate in sorted(glob.glob(pattern), reverse=True):
            found = _from_bashrc(Path(candidate))
            if found is not None:
                return found

    hint = (
        "no WM_PROJECT_DIR with etc/controlDict, no OpenFOAM program (blockMesh) on PATH, and "
        "no etc/bashrc under /usr/lib/openfoam or /opt"
    )
    if project:
        hint = f"WM_PROJECT_DIR={project} has no etc/controlDict; " + hint
    raise CaseError(
        f"OpenFOAM not found: {hint}. Fix: source <install>/etc/bashrc before starting "
        f"Python, set {BASHRC_ENV}=<install>/etc/bashrc, or install OpenFOAM "
        "(e.g. the 'openfoam' Debian package)."
    )


def run_tool(
    argv: Sequence[str],
    cwd: Path,
    log_name: str,
    installation: OpenFOAMInstallation,
    *,
    timeout: float | None = None,
    extra_env: Mapping[str, str] | None = None,
    append: bool = False,
) -> None:
    """Run an OpenFOAM tool in ``cwd`` with its output in ``cwd/log_name``.

    OpenFOAM tools can exit 0 after a FOAM FATAL ERROR in some code paths, so the log is
    checked too; failures raise :class:`CaseError` naming the log and quoting its tail.
    ``append`` adds to the log (several runs of one step, e.g. pre-run segments).
    """
    env = installation.environ()
    if extra_env:
        env.update(extra_env)
    program = _which(argv[0], env.get("PATH", os.defpath))
    if program is None:
        raise CaseError(
            f"{argv[0]}: not found on PATH of the OpenFOAM environment "
            f"({installation.project_dir}); install the OpenFOAM program or fix PATH"
        )
    log_path = cwd / log_name
    start = log_path.stat().st_size if append and log_path.is_file() else 0
    try:
        with log_path.open("ab" if append else "wb") as log:
            proc = subprocess.run(
                [program, *argv[1:]],
                cwd=cwd,
                env=env,
                stdin=subprocess.DEVNULL,
                stdout=log,
                stderr=subprocess.STDOUT,
                timeout=timeout,
                check=False,
            )
    except subprocess.TimeoutExpired:
        raise CaseError(
            f"{' '.join(argv)} in {cwd} took longer than {timeout} s; see {log_path}"
        ) from None
    with log_path.open("rb") as log:
        log.seek(start)
        text = log.read().decode(errors="replace")
    if proc.returncode != 0 or "FOAM FATAL" in text:
        tail = "\n".join("    " + line for line in text.rstrip().splitlines()[-25:])
        raise CaseError(
            f"{' '.join(argv)} failed in {cwd} (exit status {proc.returncode}); "
            f"log: {log_path}\n{tail}"
        )


def mpi_env() -> dict[str, str]:
    """Variables mpirun needs here: Open MPI refuses to run as root without them."""
    if hasattr(os, "geteuid") and os.geteuid() == 0:
        return {"OMPI_ALLOW_RUN_AS_ROOT": "1", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1"}
    return {}
