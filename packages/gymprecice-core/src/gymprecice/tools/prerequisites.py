"""What ``gymprecice install`` needs on the machine before it builds anything.

A build that starts and fails five minutes later on a missing Boost is the worst way to learn
what to install. Each install step lists its prerequisites (a compiler, CMake, a library's
headers, a solver), each with a cheap probe and the Debian/Ubuntu packages that provide it;
``gymprecice install`` probes them all first and names everything missing at once, with one
``apt-get install`` line, before any build starts.

The probes look where a compiler and CMake would (``PATH``, ``pkg-config``, the standard
include and library directories plus ``CPATH``/``LIBRARY_PATH``): they decide whether to start,
and the build itself stays the final judge.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sysconfig
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

__all__ = [
    "Prerequisite",
    "command_output",
    "describe_missing",
    "header",
    "library",
    "missing",
    "pkg_config",
    "program",
]


def command_output(argv: Sequence[str], timeout: float = 20) -> str | None:
    """stdout of a small probe command (``pkg-config``, ``dpkg-query``), or ``None`` if it
    is missing, fails or hangs: the probes only decide whether something is there."""
    try:
        proc = subprocess.run(
            list(argv), capture_output=True, text=True, timeout=timeout, stdin=subprocess.DEVNULL
        )
    except (OSError, subprocess.TimeoutExpired):
        return None
    return proc.stdout.strip() if proc.returncode == 0 else None


@dataclass(frozen=True)
class Prerequisite:
    """Something a build needs: its name for people, a probe, what provides it on Debian."""

    title: str
    present: Callable[[], bool]
    debian: tuple[str, ...] = ()

    def __hash__(self) -> int:  # the probe is a closure: identity is the title
        return hash(self.title)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Prerequisite) and other.title == self.title


def _multiarch() -> str:
    return str(sysconfig.get_config_var("MULTIARCH") or "")


def _dirs(env_vars: Sequence[str], standard: Sequence[str]) -> list[Path]:
    dirs = [p for var in env_vars for p in os.environ.get(var, "").split(os.pathsep) if p]
    arch = _multiarch()
    for base in standard:
        dirs.append(base)
        if arch:
            dirs.append(f"{base}/{arch}")
    return [Path(d) for d in dict.fromkeys(dirs)]


def include_dirs() -> list[Path]:
    return _dirs(
        ("CPATH", "CPLUS_INCLUDE_PATH", "C_INCLUDE_PATH"), ("/usr/local/include", "/usr/include")
    )


def library_dirs() -> list[Path]:
    return _dirs(
        ("LIBRARY_PATH", "LD_LIBRARY_PATH"),
        ("/usr/local/lib", "/usr/local/lib64", "/usr/lib", "/usr/lib64", "/lib"),
    )


def program(title: str, *names: str, debian: Iterable[str] = ()) -> Prerequisite:
    """Any of the programs ``names`` on ``PATH``."""
    return Prerequisite(title, lambda: any(shutil.which(n) for n in names), tuple(debian))


def header(title: str, *relative: str, debian: Iterable[str] = ()) -> Prerequisite:
    """Any of the header files ``relative`` (to an include directory) present."""

    def present() -> bool:
        return any((d / r).is_file() for d in include_dirs() for r in relative)

    return Prerequisite(title, present, tuple(debian))


def library(title: str, *stems: str, debian: Iterable[str] = ()) -> Prerequisite:
    """Every library ``stems`` (``boost_log`` for ``libboost_log.so*``) in a library directory."""

    def present() -> bool:
        return all(any(any(d.glob(f"lib{s}.so*")) for d in library_dirs()) for s in stems)

    return Prerequisite(title, present, tuple(debian))


def pkg_config(title: str, module: str, *headers: str, debian: Iterable[str] = ()) -> Prerequisite:
    """A ``pkg-config`` module, or (without pkg-config's answer) one of its ``headers``."""

    def present() -> bool:
        if command_output(["pkg-config", "--exists", module]) is not None:
            return True
        return any((d / h).is_file() for d in include_dirs() for h in headers)

    return Prerequisite(title, present, tuple(debian))


def all_of(title: str, *parts: Prerequisite) -> Prerequisite:
    """One prerequisite made of several probes (Boost: headers and libraries)."""
    debian = tuple(dict.fromkeys(p for part in parts for p in part.debian))
    return Prerequisite(title, lambda: all(part.present() for part in parts), debian)


def python_headers() -> Prerequisite:
    """``Python.h`` of the running interpreter (compiling a C extension such as pyprecice)."""
    include = sysconfig.get_paths().get("include") or ""
    version = sysconfig.get_python_version()
    return Prerequisite(
        f"the Python {version} headers (Python.h)",
        lambda: (Path(include) / "Python.h").is_file(),
        (f"python{version}-dev",),
    )


# The pieces preCICE's own build needs (https://precice.org/installation-source-dependencies.html).
CXX = program("a C++ compiler (g++ or clang++)", "c++", "g++", "clang++", debian=("g++",))
MAKE = program("make", "make", debian=("make",))
CMAKE = program("CMake", "cmake", debian=("cmake",))
PKG_CONFIG = program("pkg-config", "pkg-config", "pkgconf", debian=("pkg-config",))
BOOST = all_of(
    "Boost (headers; log, thread, system, filesystem, program_options libraries)",
    header("Boost headers", "boost/version.hpp", debian=("libboost-dev",)),
    library(
        "Boost libraries",
        "boost_log",
        "boost_thread",
        "boost_system",
        "boost_filesystem",
        "boost_program_options",
        debian=(
            "libboost-log-dev",
            "libboost-thread-dev",
            "libboost-system-dev",
            "libboost-filesystem-dev",
            "libboost-program-options-dev",
        ),
    ),
)
EIGEN = pkg_config("Eigen 3", "eigen3", "eigen3/Eigen/Core", debian=("libeigen3-dev",))
LIBXML2 = pkg_config("libxml2", "libxml-2.0", "libxml2/libxml/parser.h", debian=("libxml2-dev",))

#: pyprecice imports mpi4py, which loads an MPI library at import (preCICE itself is built
#: without MPI: gymprecice couples over sockets)
MPI = library("an MPI library (Open MPI or MPICH, for mpi4py)", "mpi", debian=("libopenmpi-dev",))


def missing(prerequisites: Iterable[Prerequisite]) -> list[Prerequisite]:
    """Those whose probe says they are not there (each once, in order)."""
    return [p for p in dict.fromkeys(prerequisites) if not p.present()]


def describe_missing(absent: Sequence[Prerequisite]) -> str:
    """``"CMake, Eigen 3 (Debian/Ubuntu: sudo apt-get install cmake libeigen3-dev)"``."""
    names = ", ".join(p.title for p in absent)
    packages = list(dict.fromkeys(d for p in absent for d in p.debian))
    if not packages:
        return names
    return f"{names} (Debian/Ubuntu: sudo apt-get install {' '.join(packages)})"
