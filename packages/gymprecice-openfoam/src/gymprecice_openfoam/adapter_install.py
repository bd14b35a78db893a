"""Build the OpenFOAM-preCICE adapter against the installed OpenFOAM (``gymprecice install``).

Two routes, chosen by what the OpenFOAM installation offers:

* **An OpenFOAM with headers and** ``wmake`` (a source build, the openfoam.com or Foundation
  packages, anything whose ``etc/bashrc`` was sourced): the adapter's own ``Allwmake``, in
  that environment, with ``FOAM_USER_LIBBIN`` pointing at the stack prefix.
* **Debian's** ``openfoam`` **package** (v1912) ships neither headers nor ``wmake``. They come
  from the same release's sources, Debian's source package (``apt-get source openfoam``, or
  its ``.orig`` archive in ``$GYMPRECICE_SOURCES``): only ``src/`` and ``wmake/`` are unpacked,
  wmake's two helper programs are compiled, the ``lnInclude`` directories the adapter's
  ``Make/options`` names are created, and ``Allwmake`` links against Debian's libraries in
  ``/usr/lib`` (the ``linux64GccDPInt32Opt`` build Debian ships).

The library lands in ``<prefix>/lib``; the plugin puts that directory on ``LD_LIBRARY_PATH``
of every OpenFOAM process it starts (OpenFOAM ``dlopen``s function objects by bare name), so
the case's ``libs ("libpreciceAdapterFunctionObject.so");`` works without sourcing anything.
"""

from __future__ import annotations

import os
import re
import shutil
import tarfile
from pathlib import Path

from gymprecice.plugin import (
    CXX,
    MAKE,
    BuildContext,
    BuildError,
    GymPreciceError,
    InstallStep,
    Prerequisite,
    SourceArchive,
    command_output,
    stack_prefix,
)
from gymprecice_openfoam.installation import ADAPTER_LIBRARY, find_openfoam

ADAPTER_VERSION = "1.3.1"
ADAPTER_ARCHIVE = SourceArchive(
    filename=f"openfoam-adapter-{ADAPTER_VERSION}.tar.gz",
    sha256="96a441cfe08cf369c3d9b0269f65583bdb4686afcc097e9c4fe7baaba82fed24",
    url=f"https://github.com/precice/openfoam-adapter/archive/refs/tags/v{ADAPTER_VERSION}.tar.gz",
    top=f"openfoam-adapter-{ADAPTER_VERSION}",
)

#: Debian's source archive of the OpenFOAM it packages, by Debian upstream version.
DEBIAN_SOURCES = {
    "1912.200626": SourceArchive(
        filename="openfoam_1912.200626.orig.tar.bz2",
        sha256="c75ca0f04cc4f49708296c1926cbde9d0138b3fef298fed54270dfe29e2df404",
        top="openfoam-OpenFOAM-v1912.200626",
    )
}

#: The build Debian ships (and wmake's variables for it).
DEBIAN_WM_ENV = {
    "WM_PROJECT": "OpenFOAM",
    "WM_ARCH": "linux64",
    "WM_ARCH_OPTION": "64",
    "WM_COMPILER": "Gcc",
    "WM_COMPILER_TYPE": "system",
    "WM_COMPILER_LIB_ARCH": "64",
    "WM_PRECISION_OPTION": "DP",
    "WM_LABEL_SIZE": "32",
    "WM_LABEL_OPTION": "Int32",
    "WM_COMPILE_OPTION": "Opt",
    "WM_OPTIONS": "linux64GccDPInt32Opt",
    "WM_MPLIB": "SYSTEMOPENMPI",
    "WM_OSTYPE": "POSIX",
    "FOAM_LIBBIN": "/usr/lib",
}

NO_HEADERS = (
    "this OpenFOAM ships no headers and no wmake, and it is not a Debian OpenFOAM whose source "
    "package can supply them; install an OpenFOAM with its headers (a source build or the "
    "openfoam.com packages), source its etc/bashrc (or set GYMPRECICE_OPENFOAM_BASHRC) and run "
    "`gymprecice install openfoam-adapter` again"
)


def _debian_openfoam_version() -> str | None:
    """Debian's version of the installed ``openfoam`` package (``1912.200626-1``), if any."""
    out = command_output(["dpkg-query", "-W", "--showformat=${Status}\t${Version}", "openfoam"])
    status, _, version = (out or "").partition("\t")
    return version if status.endswith(" installed") and version else None


def _built(prefix: Path) -> Path | None:
    library = prefix / "lib" / ADAPTER_LIBRARY
    return library if library.is_file() else None


def _found_elsewhere() -> str | None:
    """An adapter library OpenFOAM already finds outside the stack prefix."""
    try:
        installation = find_openfoam()
    except GymPreciceError:
        return None
    own = stack_prefix() / "lib"
    for directory in installation.library_dirs():
        candidate = directory / ADAPTER_LIBRARY
        if candidate.is_file() and directory.resolve() != own.resolve():
            return str(candidate)
    return None


def _key_extra() -> str:
    try:
        installation = find_openfoam()
    except GymPreciceError:
        return "no OpenFOAM"
    return f"{installation.project_dir} {installation.version} {_debian_openfoam_version()}"


def _build(ctx: BuildContext) -> None:
    try:
        installation = find_openfoam()
    except GymPreciceError as exc:
        raise BuildError(f"{ctx.step.title}: {exc}") from None
    env = {**installation.environ(), **ctx.pkg_config_env()}
    env.update(FOAM_USER_LIBBIN=str(ctx.prefix / "lib"), WM_NCOMPPROCS=str(ctx.jobs))
    headers = Path(env.get("FOAM_SRC") or installation.project_dir / "src")
    debian = None
    if not (shutil.which("wmake", path=env.get("PATH")) and (headers / "OpenFOAM").is_dir()):
        debian = _debian_openfoam_version()
        if installation.layout != "debian" or debian is None:
            raise BuildError(f"{ctx.step.title}: {installation.project_dir}: {NO_HEADERS}")
    adapter = ctx.unpack(ADAPTER_ARCHIVE)
    (ctx.prefix / "lib").mkdir(parents=True, exist_ok=True)
    if debian is None:
        ctx.say(f"[install]   building against {installation.project_dir} (its wmake)")
    else:
        env.update(_debian_build_tree(ctx, debian, adapter))
    ctx.say("[install]   compiling the adapter with wmake (about a minute)")
    ctx.run(["./Allwmake"], cwd=adapter, env=env)
    log = (adapter / "Allwmake.log").read_text(errors="replace")
    if "=== OK: Building completed successfully! ===" not in log:
        with ctx.log_path.open("a") as f:
            f.write(log + (adapter / "wmake.log").read_text(errors="replace")[-20000:])
        raise BuildError(f"{ctx.step.title}: Allwmake did not report success")


def _debian_build_tree(ctx: BuildContext, debian_version: str, adapter: Path) -> dict[str, str]:
    """Unpack Debian's OpenFOAM sources (headers, wmake) and return wmake's environment."""
    # a binary-only rebuild (1912.200626-1+b1) comes from the source version 1912.200626-1
    source_version = re.sub(r"\+b\d+$", "", debian_version)
    upstream = source_version.rsplit("-", 1)[0]
    archive = DEBIAN_SOURCES.get(upstream)
    tarball = None
    if archive is not None:
        try:
            tarball = archive.locate(lambda _msg: None)
        except BuildError as exc:
            if "checksum mismatch" in str(exc):
                raise
    if tarball is None:
        ctx.say(f"[install]   fetching Debian's source package openfoam {source_version}")
        fetch = ctx.work / "debian-source"
        fetch.mkdir()
        try:
            ctx.run(
                ["apt-get", "source", "--download-only", f"openfoam={source_version}"],
                cwd=fetch,
            )
        except BuildError:
            raise BuildError(
                f"{ctx.step.title}: Debian's OpenFOAM ships no headers and its source package "
                f"openfoam {source_version} could not be fetched; add a `deb-src` entry for "
                "your Debian release to the apt sources and run `sudo apt-get update` (from a "
                "clone of the repository, `bash scripts/setup.sh` does this), or put "
                "openfoam_<version>.orig.tar.* in $GYMPRECICE_SOURCES"
            ) from None
        tarball = next(iter(sorted(fetch.glob("openfoam_*.orig.tar.*"))), None)
        if tarball is None:
            raise BuildError(f"{ctx.step.title}: apt-get source gave no openfoam .orig archive")
    ctx.say("[install]   unpacking OpenFOAM's src/ and wmake/ from the source package")
    tree = ctx.work / "openfoam-sources"
    with tarfile.open(tarball) as tar:
        wanted = [m for m in tar if re.match(r"^[^/]+/(src|wmake)(/|$)", m.name) is not None]
        tar.extractall(tree, members=wanted, filter="tar")
    roots = sorted(p for p in tree.iterdir() if p.is_dir())
    if not roots:
        raise BuildError(f"{ctx.step.title}: {tarball} holds no src/ and wmake/")
    project = roots[0]
    version = "v" + upstream.split(".", 1)[0]
    wm = {
        **DEBIAN_WM_ENV,
        "WM_PROJECT_VERSION": version,
        "WM_PROJECT_DIR": str(project),
        "WM_DIR": str(project / "wmake"),
        "FOAM_SRC": str(project / "src"),
        "LIB_SRC": str(project / "src"),
    }
    wm["PATH"] = os.pathsep.join([str(project / "wmake"), os.environ.get("PATH", os.defpath)])
    env = {**os.environ, **ctx.pkg_config_env(), **wm}
    ctx.run(["make"], cwd=project / "wmake" / "src", env=env)
    for directory in _ln_include_dirs(adapter / "Make" / "options", project / "src"):
        ctx.run(["wmakeLnInclude", "-u", "."], cwd=directory, env=env)
    # Only the build sees these: OpenFOAM programs keep Debian's own WM_PROJECT_DIR at run time.
    return wm


def _ln_include_dirs(options: Path, src: Path) -> list[Path]:
    """The library directories whose ``lnInclude`` the adapter's ``Make/options`` uses."""
    names = re.findall(r"\$\(LIB_SRC\)/([\w/]+?)/lnInclude", options.read_text())
    dirs = [src / "OpenFOAM", src / "OSspecific" / "POSIX"] + [src / n for n in names]
    return [d for d in dict.fromkeys(dirs) if d.is_dir()]


def _openfoam_present() -> bool:
    try:
        find_openfoam()
    except GymPreciceError:
        return False
    return True


#: probed before the build starts (gymprecice.prerequisites)
OPENFOAM = Prerequisite(
    "OpenFOAM (its programs on PATH, or its etc/bashrc sourced)", _openfoam_present, ("openfoam",)
)


def openfoam_adapter_step() -> InstallStep:
    return InstallStep(
        name="openfoam-adapter",
        title=f"OpenFOAM-preCICE adapter {ADAPTER_VERSION}",
        version=ADAPTER_VERSION,
        archive=ADAPTER_ARCHIVE,
        build=_build,
        built=_built,
        found=_found_elsewhere,
        requires=("precice",),
        needs=(
            "install OpenFOAM (Debian/Ubuntu: `sudo apt-get install openfoam`), a C++ compiler "
            "and make, and run it again"
        ),
        key_extra=_key_extra(),
        prerequisites=(CXX, MAKE, OPENFOAM),
        about_seconds=90,
    )
