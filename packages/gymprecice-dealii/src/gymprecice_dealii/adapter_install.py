"""Build the deal.II-preCICE adapter's ``elasticity`` program (``gymprecice install``).

CMake against the installed deal.II and the stack's preCICE, 2-D (``-DDIM=2``, the
perpendicular flap) and **Release**: without it, ``DEAL_II_INITIALIZE_CACHED_VARIABLES``
picks deal.II's default and may build a Debug program against ``libdeal.ii.g.so`` that runs
an FSI many times slower without a word. The program is copied to ``<prefix>/bin``; its build
RPATH points at the stack's ``libprecice``, and the plugin finds it there without ``PATH``.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

from gymprecice.plugin import (
    CMAKE,
    CXX,
    MAKE,
    BuildContext,
    BuildError,
    InstallStep,
    Prerequisite,
    SourceArchive,
    header,
    stack_prefix,
)

ADAPTER_REF = "2ab217d"
ADAPTER_ARCHIVE = SourceArchive(
    filename=f"dealii-adapter-{ADAPTER_REF}.tar.gz",
    sha256="2e7bb2d6f0ca362650982789b519c3c7ddad5d74639c954c10b204762ff05a81",
    url=f"https://github.com/precice/dealii-adapter/archive/{ADAPTER_REF}.tar.gz",
    top=f"dealii-adapter-{ADAPTER_REF}",
)
PROGRAM = "elasticity"
CMAKE_OPTIONS = ("-DDIM=2", "-DCMAKE_BUILD_TYPE=Release")
_DEALII_HEADERS = header("deal.II", "deal.II/base/config.h", debian=("libdeal.ii-dev",))
#: probed before the build starts (gymprecice.prerequisites): the headers where Debian puts
#: them, or a deal.II of its own prefix named by DEAL_II_DIR (CMake's own way to find it)
DEALII = Prerequisite(
    "deal.II (>= 9.2, with its headers)",
    lambda: bool(os.environ.get("DEAL_II_DIR")) or _DEALII_HEADERS.present(),
    _DEALII_HEADERS.debian,
)


def _built(prefix: Path) -> Path | None:
    program = prefix / "bin" / PROGRAM
    return program if program.is_file() else None


def _found_elsewhere() -> str | None:
    found = shutil.which(PROGRAM)
    if found is None or Path(found).resolve() == (stack_prefix() / "bin" / PROGRAM).resolve():
        return None
    return found


def _build(ctx: BuildContext) -> None:
    source = ctx.unpack(ADAPTER_ARCHIVE)
    build = ctx.work / "build"
    env = ctx.pkg_config_env()
    precice_cmake = ctx.prefix / "lib" / "cmake" / "precice"
    extra = [f"-Dprecice_DIR={precice_cmake}"] if precice_cmake.is_dir() else []
    ctx.say("[install]   configuring with CMake against deal.II")
    try:
        ctx.run(["cmake", "-S", source, "-B", build, *CMAKE_OPTIONS, *extra], cwd=ctx.work, env=env)
    except BuildError:
        raise BuildError(
            f"{ctx.step.title}: CMake failed; is deal.II (>= 9.2) installed? Debian/Ubuntu: "
            "`sudo apt-get install libdeal.ii-dev` (from a clone of the repository, "
            "`bash scripts/setup.sh` does this); see the log for CMake's own words"
        ) from None
    ctx.say("[install]   compiling elasticity (about a minute)")
    ctx.run(["cmake", "--build", build, "--parallel", str(ctx.jobs)], cwd=ctx.work, env=env)
    target = ctx.prefix / "bin" / PROGRAM
    target.parent.mkdir(parents=True, exist_ok=True)
    staged = target.with_name(PROGRAM + ".part")
    shutil.copy2(build / PROGRAM, staged)
    staged.replace(target)


def elasticity_step() -> InstallStep:
    return InstallStep(
        name="dealii-adapter",
        title=f"deal.II-preCICE adapter ({PROGRAM}, {ADAPTER_REF})",
        version=ADAPTER_REF,
        archive=ADAPTER_ARCHIVE,
        build=_build,
        built=_built,
        found=_found_elsewhere,
        requires=("precice",),
        needs="install deal.II, a C++ compiler, make and CMake, and run it again",
        prerequisites=(CXX, MAKE, CMAKE, DEALII),
        key_extra=" ".join(CMAKE_OPTIONS),
        about_seconds=100,
    )
