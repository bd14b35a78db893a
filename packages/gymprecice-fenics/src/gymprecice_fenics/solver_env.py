"""The FEniCS solver environment: where it lives, what it holds, how it is built.

Legacy FEniCS (dolfin 2019.2) is a Debian package built for the system's ``/usr/bin/python3``
only, and the fenicsprecice adapter requires ``numpy<2``, while gymprecice's own environment
has numpy 2. So FEniCS participants run in an interpreter of their own: a virtual
environment on the system Python with ``--system-site-packages`` (Debian's dolfin, numpy,
scipy and mpi4py), plus pyprecice compiled against the stack's preCICE and fenicsprecice.

It lives in the stack prefix (``<prefix>/fenics``) next to preCICE, so every checkout and
venv of the same user reuses it, and ``gymprecice install fenics`` builds it (a second run
takes seconds). ``$GYMPRECICE_FENICS_PYTHON`` names another interpreter to use instead.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path

from gymprecice.plugin import (
    CXX,
    PKG_CONFIG,
    BuildContext,
    BuildError,
    InstallStep,
    Prerequisite,
    command_output,
    stack_prefix,
)

__all__ = [
    "DEBIAN_PACKAGES",
    "FENICSPRECICE_VERSION",
    "PYTHON_ENV",
    "SYSTEM_PYTHON",
    "EnvironmentReport",
    "fenics_install_step",
    "fenics_python",
    "probe",
]

#: the interpreter Debian's python3-dolfin is built for
SYSTEM_PYTHON = "/usr/bin/python3"
#: Debian packages the environment is made of (the set-up installs them like OpenFOAM)
DEBIAN_PACKAGES = ("python3-dolfin", "python3-scipy", "python3-venv")
FENICSPRECICE_VERSION = "2.3.1"
PYPRECICE_VERSION = "3.4.0"
#: names another interpreter to run FEniCS participants with
PYTHON_ENV = "GYMPRECICE_FENICS_PYTHON"
ENV_DIR = "fenics"

INSTALL_ADVICE = (
    "install Debian's FEniCS (Debian/Ubuntu: `sudo apt-get install python3-dolfin "
    "python3-scipy python3-venv`), then build the solver environment: `gymprecice install "
    "fenics` (from a clone of the repository, `bash scripts/setup.sh` does both)"
)

# Run by the candidate interpreter: what it can import, and the versions that matter.
_PROBE = r"""
import json, sys
out = {"python": sys.version.split()[0], "missing": {}}
for name in ("numpy", "dolfin", "precice", "fenicsprecice"):
    try:
        module = __import__(name)
    except Exception as exc:
        out["missing"][name] = f"{type(exc).__name__}: {exc}"
        continue
    try:
        import importlib.metadata as md
        out[name] = md.version({"dolfin": "fenics-dolfin"}.get(name, name))
    except Exception:
        out[name] = str(getattr(module, "__version__", "") or "")
if "precice" in sys.modules:
    v = sys.modules["precice"].get_version_information()
    out["precice"] = (v.decode() if isinstance(v, bytes) else str(v)).split(";")[0]
print("GYMPRECICE-PROBE " + json.dumps(out))
"""


def env_dir(prefix: Path | None = None) -> Path:
    """The solver environment's directory in the stack prefix."""
    return (stack_prefix() if prefix is None else prefix) / ENV_DIR


def fenics_python(prefix: Path | None = None) -> str:
    """The interpreter FEniCS participants run with (may not exist: see :func:`probe`)."""
    explicit = os.environ.get(PYTHON_ENV)
    if explicit:
        return explicit
    return str(env_dir(prefix) / "bin" / "python")


@dataclass(frozen=True)
class EnvironmentReport:
    """What an interpreter offers a FEniCS participant, and what is wrong with it."""

    python: str
    versions: dict[str, str]
    problems: tuple[str, ...]

    @property
    def ok(self) -> bool:
        return not self.problems

    def summary(self) -> str:
        shown = ", ".join(f"{k} {v}" for k, v in self.versions.items() if v)
        return f"{self.python} ({shown})"


_CACHE: dict[str, EnvironmentReport] = {}


def probe(python: str | None = None, *, refresh: bool = False) -> EnvironmentReport:
    """Import dolfin, numpy, precice and fenicsprecice in ``python`` and judge the result.

    Runs in a child interpreter: the environment is not this one, and a broken MPI or
    library can abort an importer. That costs a second of CPU and nearly 3 s (dolfin's
    import), paid by every ``gymprecice doctor`` and by every lab command, whose manifest
    records the doctor's report: so the answer is cached for the process, and a healthy one
    of a virtual environment also in that environment's folder, for as long as no file it
    depends on changes (:func:`_fingerprint`). Problems name the piece and the fix: no
    interpreter, a missing module, numpy 2 (which fenicsprecice 2.x and Debian's dolfin do
    not support), a pyprecice of preCICE v2.
    """
    python = python or fenics_python()
    if not refresh and python in _CACHE:
        return _CACHE[python]
    key = _fingerprint(python)
    report = None if refresh else _stored(python, key)
    if report is None:
        report = _probe(python)
        if report.ok and key is not None:
            _store(python, key, report)
    _CACHE[python] = report
    return report


#: the file beside an interpreter's environment that keeps its last healthy probe
_STORED = ".gymprecice-probe.json"


def _environment_root(python: str) -> Path:
    return Path(python).parent.parent


def _fingerprint(python: str) -> str | None:
    """Size and modification time of every file the probe's answer depends on: the
    interpreter, the environment's configuration and site-packages, Debian's package
    database (dolfin, numpy, scipy and mpi4py are Debian's) and the stack's preCICE
    library (pyprecice links it); ``None`` when the interpreter is missing."""
    root = _environment_root(python)
    paths = [
        Path(python),
        root / "pyvenv.cfg",
        *sorted(root.glob("lib/python3*/site-packages")),
        Path("/var/lib/dpkg/status"),
        stack_prefix() / "lib" / "libprecice.so",
    ]
    stamps = []
    for path in paths:
        try:
            info = path.stat()
        except OSError:
            if path == Path(python):
                return None
            stamps.append(f"{path}:-")
            continue
        stamps.append(f"{path}:{info.st_size}:{info.st_mtime_ns}")
    env = [f"{k}={os.environ.get(k, '')}" for k in ("LD_LIBRARY_PATH", "PYTHONPATH")]
    return "|".join([os.path.realpath(python), *stamps, *env])


def _stored(python: str, key: str | None) -> EnvironmentReport | None:
    """The healthy probe kept for ``python`` when nothing it depends on has changed."""
    if key is None:
        return None
    root = _environment_root(python)
    if not (root / "pyvenv.cfg").is_file():
        return None
    try:
        data = json.loads((root / _STORED).read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(data, dict) or data.get("key") != key:
        return None
    versions = data.get("versions")
    if not isinstance(versions, dict):
        return None
    return EnvironmentReport(python, {str(k): str(v) for k, v in versions.items()}, ())


def _store(python: str, key: str, report: EnvironmentReport) -> None:
    """Keep a healthy probe in a virtual environment's folder (whole or not at all; an
    interpreter outside a virtual environment, or an unwritable one, keeps none)."""
    root = _environment_root(python)
    if not (root / "pyvenv.cfg").is_file():
        return
    target = root / _STORED
    partial = target.with_name(f"{_STORED}.{os.getpid()}.partial")
    try:
        partial.write_text(json.dumps({"key": key, "versions": report.versions}))
        os.replace(partial, target)
    except OSError:
        with contextlib.suppress(OSError):
            partial.unlink()


def _probe(python: str) -> EnvironmentReport:
    if not Path(python).is_file() or not os.access(python, os.X_OK):
        return EnvironmentReport(
            python,
            {},
            (f"no FEniCS solver environment: {python} does not exist; {INSTALL_ADVICE}",),
        )
    try:
        proc = subprocess.run(
            [python, "-c", _PROBE],
            capture_output=True,
            text=True,
            timeout=120,
            stdin=subprocess.DEVNULL,
            env={**os.environ, "OMP_NUM_THREADS": "1"},
        )
    except (OSError, subprocess.TimeoutExpired) as exc:
        return EnvironmentReport(python, {}, (f"{python} cannot run: {exc}; {INSTALL_ADVICE}",))
    line = next((ln for ln in proc.stdout.splitlines() if ln.startswith("GYMPRECICE-PROBE ")), None)
    if line is None:
        tail = (proc.stderr or proc.stdout).strip().splitlines()[-1:] or [f"exit {proc.returncode}"]
        return EnvironmentReport(
            python, {}, (f"{python} failed to import its modules ({tail[0]}); {INSTALL_ADVICE}",)
        )
    found = json.loads(line.split(" ", 1)[1])
    missing: dict[str, str] = found.pop("missing")
    versions = {k: str(v) for k, v in found.items()}
    problems = [_missing_advice(python, name, why) for name, why in missing.items()]
    numpy = versions.get("numpy", "")
    if numpy and int(numpy.split(".")[0]) >= 2:
        problems.append(
            f"{python} has numpy {numpy}, but fenicsprecice {FENICSPRECICE_VERSION} and Debian's "
            "dolfin need numpy<2; use an environment on the system Python with Debian's numpy "
            "(`gymprecice install fenics --force` rebuilds it), not one with numpy 2"
        )
    precice = versions.get("precice", "")
    if precice and not precice.lstrip("v").startswith("3."):
        problems.append(
            f"{python}: pyprecice is built against preCICE {precice}, fenicsprecice "
            f"{FENICSPRECICE_VERSION} needs preCICE v3; rebuild with `gymprecice install fenics "
            "--force`"
        )
    return EnvironmentReport(python, versions, tuple(problems))


def _missing_advice(python: str, name: str, why: str) -> str:
    fix = {
        "dolfin": "install Debian's FEniCS: `apt-get install python3-dolfin`, and make the "
        "environment see it (a venv on /usr/bin/python3 with --system-site-packages)",
        "numpy": "install Debian's numpy (`apt-get install python3-numpy`)",
        "precice": "build pyprecice into it: `gymprecice install fenics`",
        "fenicsprecice": f"install it: `gymprecice install fenics` (fenicsprecice "
        f"{FENICSPRECICE_VERSION})",
    }[name]
    return f"{python} cannot import {name} ({why}); {fix}"


# -- the install step ---------------------------------------------------------------------------


def _system_numpy() -> str | None:
    try:
        proc = subprocess.run(
            [SYSTEM_PYTHON, "-c", "import dolfin, numpy; print(numpy.__version__)"],
            capture_output=True,
            text=True,
            timeout=120,
            stdin=subprocess.DEVNULL,
        )
    except (OSError, subprocess.TimeoutExpired):
        return None
    return proc.stdout.strip() if proc.returncode == 0 else None


def _build(ctx: BuildContext) -> None:
    numpy = _system_numpy()
    if numpy is None:
        raise BuildError(
            f"{ctx.step.title}: {SYSTEM_PYTHON} cannot import dolfin; install Debian's FEniCS "
            f"(Debian/Ubuntu: `sudo apt-get install {' '.join(DEBIAN_PACKAGES)}`) and run "
            "`gymprecice install fenics` again"
        )
    target = env_dir(ctx.prefix)
    # A venv records its own path in its scripts: build it where it will live. A failed
    # build leaves no stamp, and the next run starts from scratch.
    shutil.rmtree(target, ignore_errors=True)
    ctx.say(f"[install]   virtual environment on {SYSTEM_PYTHON} (Debian's dolfin, numpy {numpy})")
    ctx.run([SYSTEM_PYTHON, "-m", "venv", "--system-site-packages", target], cwd=ctx.work)
    # Pin what Debian provides: pip must never swap numpy 2 in under dolfin.
    constraints = ctx.work / "constraints.txt"
    constraints.write_text(f"numpy=={numpy}\n")
    libdir = ctx.prefix / "lib"
    env = ctx.pkg_config_env()
    # pyprecice links the stack's libprecice; the RPATH finds it without LD_LIBRARY_PATH.
    env["LDFLAGS"] = f"{os.environ.get('LDFLAGS', '')} -Wl,-rpath,{libdir}".strip()
    ctx.say("[install]   pyprecice against the stack's preCICE, and fenicsprecice (about 20 s)")
    ctx.run(
        [
            target / "bin" / "python",
            "-m",
            "pip",
            "install",
            "--disable-pip-version-check",
            "--no-cache-dir",
            "--no-binary",
            "pyprecice",
            "-c",
            constraints,
            f"pyprecice=={PYPRECICE_VERSION}",
            f"fenicsprecice=={FENICSPRECICE_VERSION}",
        ],
        cwd=ctx.work,
        env=env,
    )
    report = probe(str(target / "bin" / "python"), refresh=True)
    if not report.ok:
        raise BuildError(f"{ctx.step.title}: built, but " + "; ".join(report.problems))


def _built(prefix: Path) -> Path | None:
    python = env_dir(prefix) / "bin" / "python"
    return python if python.is_file() else None


def _found_elsewhere() -> str | None:
    explicit = os.environ.get(PYTHON_ENV)
    if not explicit:
        return None
    report = probe(explicit)
    return f"{report.summary()} (${PYTHON_ENV})" if report.ok else None


def _system_fenics() -> bool:
    return _system_numpy() is not None and (
        command_output([SYSTEM_PYTHON, "-c", "import venv, ensurepip"]) is not None
    )


#: probed before the build starts (gymprecice.prerequisites)
SYSTEM_FENICS = Prerequisite(
    f"Debian's FEniCS for {SYSTEM_PYTHON} (python3-dolfin, python3-scipy, python3-venv)",
    _system_fenics,
    DEBIAN_PACKAGES,
)


def fenics_install_step() -> InstallStep:
    """``gymprecice install fenics``: the solver environment in ``<prefix>/fenics``."""
    return InstallStep(
        name="fenics",
        title=f"FEniCS solver environment (fenicsprecice {FENICSPRECICE_VERSION})",
        version=FENICSPRECICE_VERSION,
        build=_build,
        built=_built,
        found=_found_elsewhere,
        requires=("precice",),
        needs=f"install {' '.join(DEBIAN_PACKAGES)} from Debian and run it again",
        # pyprecice is compiled for the system Python inside the environment
        prerequisites=(SYSTEM_FENICS, CXX, PKG_CONFIG),
        key_extra=f"pyprecice {PYPRECICE_VERSION} on {SYSTEM_PYTHON}",
        about_seconds=40,
    )
