"""Core's own install steps: the preCICE library and pyprecice, its Python bindings.

preCICE is built with CMake into the stack prefix (Release, shared; no MPI, PETSc or Python
actions, which gymprecice never uses: every participant talks over sockets, so parallel
solvers run fine without preCICE's MPI communication). pyprecice compiles against it into the
running Python environment with an RPATH to the prefix, so ``import precice`` finds
``libprecice.so`` without ``LD_LIBRARY_PATH``.
"""

from __future__ import annotations

import hashlib
import importlib.util
import json
import os
import re
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

from gymprecice.tools.prerequisites import (
    BOOST,
    CMAKE,
    CXX,
    EIGEN,
    LIBXML2,
    MAKE,
    MPI,
    PKG_CONFIG,
    python_headers,
)
from gymprecice.tools.stack import (
    BuildContext,
    BuildError,
    InstallStep,
    SourceArchive,
    command_output,
)

PRECICE_VERSION = "3.4.1"
PYPRECICE_VERSION = "3.4.0"

PRECICE_ARCHIVE = SourceArchive(
    filename=f"precice-{PRECICE_VERSION}.tar.gz",
    sha256="642e9be641f3eff90c20b000c4aa66cfc46cb8d279b81a539bcd5fae63bb5075",
    url=f"https://github.com/precice/precice/archive/refs/tags/v{PRECICE_VERSION}.tar.gz",
    top=f"precice-{PRECICE_VERSION}",
)

PRECICE_CMAKE_OPTIONS = (
    "-DCMAKE_BUILD_TYPE=Release",
    "-DBUILD_SHARED_LIBS=ON",
    "-DCMAKE_INSTALL_LIBDIR=lib",
    "-DPRECICE_FEATURE_MPI_COMMUNICATION=OFF",
    "-DPRECICE_FEATURE_PETSC_MAPPING=OFF",
    "-DPRECICE_FEATURE_PYTHON_ACTIONS=OFF",
    "-DPRECICE_BINDINGS_FORTRAN=OFF",
    "-DPRECICE_CONFIGURE_PACKAGE_GENERATION=OFF",
    "-DBUILD_TESTING=OFF",
)

#: What building preCICE needs on the machine (probed before the build starts).
PRECICE_PREREQUISITES = (CXX, MAKE, CMAKE, PKG_CONFIG, BOOST, EIGEN, LIBXML2)

BUILD_NEEDS = (
    "install a C++ compiler, make, CMake, pkg-config and preCICE's libraries "
    "(Debian/Ubuntu: `sudo apt-get install g++ make cmake pkg-config libboost-all-dev "
    "libeigen3-dev libxml2-dev`; from a clone of the repository, `bash scripts/setup.sh` "
    "does this) and run it again"
)


def _pkg_config_precice() -> str | None:
    """A preCICE v3 that ``pkg-config`` finds outside the stack prefix, described."""
    version = command_output(["pkg-config", "--modversion", "libprecice"])
    if not version or not version.startswith("3."):
        return None
    libdir = command_output(["pkg-config", "--variable=libdir", "libprecice"])
    return f"preCICE {version} (pkg-config, {libdir})"


def _precice_built(prefix: Path) -> Path | None:
    library = prefix / "lib" / "libprecice.so"
    pc = prefix / "lib" / "pkgconfig" / "libprecice.pc"
    return library if library.exists() and pc.is_file() else None


def _build_precice(ctx: BuildContext) -> None:
    source = ctx.unpack(PRECICE_ARCHIVE)
    build = ctx.work / "build"
    ctx.say(f"[install]   configuring with CMake ({ctx.jobs} jobs)")
    ctx.run(
        [
            "cmake",
            "-S",
            source,
            "-B",
            build,
            f"-DCMAKE_INSTALL_PREFIX={ctx.prefix}",
            f"-DCMAKE_INSTALL_RPATH={ctx.prefix / 'lib'}",
            *PRECICE_CMAKE_OPTIONS,
        ],
        cwd=ctx.work,
    )
    ctx.say("[install]   compiling (about 3 minutes on 2 cores)")
    ctx.run(["cmake", "--build", build, "--parallel", str(ctx.jobs)], cwd=ctx.work)
    ctx.run(["cmake", "--install", build], cwd=ctx.work)


_PROBE = (
    "import precice, sys; v = precice.get_version_information(); "
    "v = v.decode() if isinstance(v, bytes) else str(v); print(precice.__file__); print(v)"
)


def probe_pyprecice(python: str = sys.executable) -> tuple[str | None, str]:
    """``(module path, preCICE version)`` of pyprecice in ``python``, or ``(None, why)``.

    Probed in a child interpreter: a pyprecice linked to a missing or mismatched library
    fails at import, and a broken MPI can abort the importing process.
    """
    try:
        proc = subprocess.run([python, "-c", _PROBE], capture_output=True, text=True, timeout=120)
    except (OSError, subprocess.TimeoutExpired) as exc:
        return None, str(exc)
    if proc.returncode != 0:
        lines = (proc.stderr or proc.stdout).strip().splitlines()
        return None, lines[-1] if lines else f"exit status {proc.returncode}"
    module, _, version = proc.stdout.strip().partition("\n")
    return module, version.split(";", 1)[0].strip()


def _pyprecice_built(prefix: Path) -> Path | None:
    module, version = probe_pyprecice()
    if module is None or not re.match(r"v?3\.", version):
        return None
    return Path(module)


def _pyprecice_found() -> str | None:
    module, version = probe_pyprecice()
    if module is None or not re.match(r"v?3\.", version):
        return None
    return f"{module} (preCICE {version})"


def _wheel_dir(prefix: Path) -> Path | None:
    """Where pyprecice's wheel built against this prefix's preCICE is kept, or ``None``.

    Compiling pyprecice takes most of a minute, and every new virtual environment (a fresh
    clone's ``.venv``, a tutorial's own) needs it: the wheel is built once per preCICE build,
    pyprecice version and Python, and installed from there afterwards. Keyed by preCICE's
    build record (the stamp's key: version, archive, CMake options), so a rebuilt preCICE of
    other options gets its own wheel. A preCICE not built in the prefix has no record: then
    nothing is reused (pip's own wheel cache is off for the same reason).
    """
    stamp = prefix / "stamps" / "precice.json"
    try:
        record = json.loads(stamp.read_text())["key"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    python = f"{sys.implementation.cache_tag}-{sysconfig.get_platform()}-{sys.abiflags}"
    key = hashlib.sha256(f"{record}|{PYPRECICE_VERSION}|{python}".encode()).hexdigest()[:16]
    return prefix / "wheels" / f"pyprecice-{PYPRECICE_VERSION}-{key}"


def _build_pyprecice(ctx: BuildContext) -> None:
    libdir = ctx.prefix / "lib"
    env = ctx.pkg_config_env()
    wheels = None
    if _precice_built(ctx.prefix) is not None:
        # The extension links the stack's libprecice; the RPATH makes `import precice` find
        # it without LD_LIBRARY_PATH (pip's wheel cache would reuse a build against
        # another preCICE, hence --no-cache-dir, and a wheel kept per preCICE build instead).
        env["LDFLAGS"] = f"{os.environ.get('LDFLAGS', '')} -Wl,-rpath,{libdir}".strip()
        wheels = _wheel_dir(ctx.prefix)
    if importlib.util.find_spec("mpi4py") is None:
        # pyprecice imports mpi4py at import time (`from mpi4py import MPI`) and declares it,
        # but pyprecice itself is installed with --no-deps below: bring it here.
        ctx.say("[install]   mpi4py (pyprecice imports it)")
        ctx.run(
            [sys.executable, "-m", "pip", "install", "--disable-pip-version-check", "mpi4py"],
            cwd=ctx.work,
        )
    pip = [sys.executable, "-m", "pip", "--disable-pip-version-check"]
    kept = sorted(wheels.glob("pyprecice-*.whl")) if wheels is not None else []
    if kept:
        ctx.say(
            f"[install]   pyprecice from its wheel built against this preCICE ({kept[-1].name})"
        )
        ctx.run([*pip, "install", "--force-reinstall", "--no-deps", kept[-1]], cwd=ctx.work)
        module, version = probe_pyprecice()
        if module is not None:
            return
        ctx.say(f"[install]   that wheel does not import ({version}): compiling afresh")
        shutil.rmtree(wheels, ignore_errors=True)
    ctx.say("[install]   compiling pyprecice against preCICE (about a minute)")
    scratch = ctx.work / "wheel"
    ctx.run(
        [*pip, "wheel", "--no-cache-dir", "--no-deps", "--no-binary", "pyprecice",
         "--wheel-dir", scratch, f"pyprecice=={PYPRECICE_VERSION}"],
        cwd=ctx.work,
        env=env,
    )  # fmt: skip
    built = sorted(scratch.glob("pyprecice-*.whl"))
    if not built:
        raise BuildError(f"pyprecice {PYPRECICE_VERSION}: pip wrote no wheel")
    ctx.run([*pip, "install", "--force-reinstall", "--no-deps", built[0]], cwd=ctx.work)
    if wheels is not None:
        # kept whole or not at all: a half-copied wheel is never found
        wheels.mkdir(parents=True, exist_ok=True)
        partial = wheels / f".{built[0].name}.partial"
        shutil.copyfile(built[0], partial)
        os.replace(partial, wheels / built[0].name)
    module, version = probe_pyprecice()
    if module is None:
        raise BuildError(f"pyprecice {PYPRECICE_VERSION} installed but does not import: {version}")


def core_install_steps() -> list[InstallStep]:
    """preCICE (into the stack prefix) and pyprecice (into this Python environment)."""
    return [
        InstallStep(
            name="precice",
            title=f"preCICE {PRECICE_VERSION}",
            version=PRECICE_VERSION,
            archive=PRECICE_ARCHIVE,
            build=_build_precice,
            built=_precice_built,
            found=_pkg_config_precice,
            needs=BUILD_NEEDS,
            key_extra=" ".join(PRECICE_CMAKE_OPTIONS),
            prerequisites=PRECICE_PREREQUISITES,
            about_seconds=150,
        ),
        InstallStep(
            name="pyprecice",
            title=f"pyprecice {PYPRECICE_VERSION}",
            version=PYPRECICE_VERSION,
            build=_build_pyprecice,
            built=_pyprecice_built,
            found=_pyprecice_found,
            requires=("precice",),
            needs=BUILD_NEEDS,
            key_extra=f"preCICE {PRECICE_VERSION}",
            per_environment=True,
            # a C extension compiled by pip (its build dependencies come from the index)
            prerequisites=(CXX, PKG_CONFIG, MPI, python_headers()),
            about_seconds=45,
        ),
    ]
