"""``manifest.json``: what a run was made with, so a result can be traced and repeated.

Every command (``train``, ``evaluate``, ``baseline``, ``open-loop``) writes one into its
output directory. A learning curve alone does not say which solver versions, which case
files or which seeds produced it; the manifest does:

* ``command``: the command line as typed, and the working directory;
* ``packages``: versions of the gymprecice distributions and of the libraries that shape
  results (Gymnasium, SB3, torch, numpy), read from the installed distributions' metadata;
* ``solvers``: the ``gymprecice doctor`` checks (pyprecice/preCICE, OpenFOAM, deal.II, ...)
  with what was found, so a run on the test double is never mistaken for a real one;
* ``config_files``: SHA-256 of every configuration file of the case (``gymprecice-config.json``,
  ``precice-config.xml``, the solvers' dictionaries): a changed mesh or time step shows up
  as a changed hash;
* ``source``: the source revision (``git describe`` when the packages run from a
  checkout; otherwise ``packages`` is what identifies the code);
* ``seeds`` and ``settings``: everything else that decides the run.

``pyprecice`` counts as present only when the doctor could import it: an installed
distribution whose preCICE library is broken would otherwise read as a real-solver run.
"""

from __future__ import annotations

import hashlib
import importlib.metadata
import json
import os
import platform
import shlex
import subprocess
import sys
from collections.abc import Iterable, Mapping, Sequence
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

__all__ = [
    "MANIFEST_NAME",
    "config_file_hashes",
    "file_sha256",
    "package_versions",
    "read_manifest",
    "solver_versions",
    "source_revision",
    "write_manifest",
]

MANIFEST_NAME = "manifest.json"

#: Distributions whose versions are recorded (missing ones are recorded as ``null``).
PACKAGES = (
    "gymprecice-core",
    "gymprecice-openfoam",
    "gymprecice-dealii",
    "gymprecice-fenics",
    "gymprecice-lab",
    "gymprecice-tutorials",
    "gymnasium",
    "stable-baselines3",
    "torch",
    "numpy",
    "pyprecice",
    "foamlib",
)

#: Case files larger than this are data (meshes, fields), not configuration.
MAX_CONFIG_BYTES = 2_000_000
#: Directories of a case that hold results or generated data rather than configuration.
_SKIPPED_DIRS = {"postProcessing", "polyMesh", "__pycache__", ".gymprecice", "precice-exchange"}
_CONFIG_DIRS = {"system", "constant"}
_CONFIG_SUFFIXES = {".json", ".xml", ".prm", ".sh", ".cfg", ".yaml", ".yml", ".toml"}


def package_versions(names: Iterable[str] = PACKAGES) -> dict[str, str | None]:
    """Installed version of each distribution (``None`` when it is not installed)."""
    out: dict[str, str | None] = {}
    for name in names:
        try:
            out[name] = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            out[name] = None
    return out


def solver_versions() -> dict[str, Any]:
    """The ``gymprecice doctor`` report: each check's result and what it found.

    The doctor probes pyprecice in a child interpreter, so a broken preCICE cannot take the
    run down while its manifest is written.
    """
    from gymprecice.tools.cli import doctor_report

    try:
        report = doctor_report()
    except Exception as exc:  # the manifest must not stop a run
        return {"ok": None, "error": f"{type(exc).__name__}: {exc}", "checks": []}
    keys = ("name", "source", "ok", "required", "detail")
    return {"ok": report["ok"], "checks": [{k: c.get(k) for k in keys} for c in report["checks"]]}


def source_revision(where: str | os.PathLike[str] | None = None) -> dict[str, Any]:
    """``git describe --always --dirty`` of the checkout this code runs from, if any.

    ``{"git": None}`` for an installed package: its versions (``packages``) identify it.
    """
    root = Path(where) if where is not None else Path(__file__).resolve().parent
    try:
        proc = subprocess.run(
            ["git", "describe", "--always", "--dirty", "--tags"],
            cwd=root,
            capture_output=True,
            text=True,
            timeout=10,
            check=False,
        )
    except (OSError, subprocess.SubprocessError):
        return {"git": None, "identified_by": "packages"}
    if proc.returncode != 0 or not proc.stdout.strip():
        return {"git": None, "identified_by": "packages"}
    return {"git": proc.stdout.strip(), "identified_by": "git"}


def file_sha256(path: str | os.PathLike[str]) -> str:
    """SHA-256 of a file (a saved model), read in chunks."""
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for chunk in iter(lambda: handle.read(1 << 20), b""):
            digest.update(chunk)
    return digest.hexdigest()


def _importable_packages(
    packages: dict[str, str | None], solvers: Mapping[str, Any]
) -> dict[str, str | None]:
    """``pyprecice``'s version only if the doctor could import it (``None`` otherwise)."""
    for check in solvers.get("checks", []):
        if check.get("name") == "pyprecice" and not check.get("ok"):
            packages = dict(packages)
            packages["pyprecice"] = None
    return packages


def _is_config_file(rel: Path) -> bool:
    parts = rel.parts
    if any(p in _SKIPPED_DIRS or p.startswith("processor") for p in parts[:-1]):
        return False
    if len(parts) == 1:
        return True
    return rel.suffix in _CONFIG_SUFFIXES or any(p in _CONFIG_DIRS for p in parts[:-1])


def config_file_hashes(case_dir: str | os.PathLike[str] | None) -> dict[str, str]:
    """``{relative path: sha256}`` of the configuration files of a case directory.

    Top-level files, everything under ``system/`` and ``constant/`` (except meshes), and
    configuration-like files (``.json``, ``.xml``, ``.prm``, scripts) anywhere else;
    results, meshes and the env's bookkeeping are left out.
    """
    if case_dir is None:
        return {}
    root = Path(case_dir)
    if root.is_file():
        root = root.parent
    out: dict[str, str] = {}
    if not root.is_dir():
        return out
    for path in sorted(root.rglob("*")):
        if not path.is_file() or path.is_symlink():
            continue
        rel = path.relative_to(root)
        if not _is_config_file(rel) or path.stat().st_size > MAX_CONFIG_BYTES:
            continue
        out[rel.as_posix()] = hashlib.sha256(path.read_bytes()).hexdigest()
    return out


def write_manifest(
    out_dir: str | os.PathLike[str],
    *,
    command: str,
    argv: Sequence[str] | None = None,
    case_dir: str | os.PathLike[str] | None = None,
    seeds: Mapping[str, Any] | None = None,
    settings: Mapping[str, Any] | None = None,
    solvers: Mapping[str, Any] | None = None,
    extra: Mapping[str, Any] | None = None,
) -> Path:
    """Write ``<out_dir>/manifest.json`` and return its path.

    ``argv`` defaults to this process's command line. ``solvers`` is a report of
    :func:`solver_versions` made earlier (the doctor's probes take seconds; a command that
    rewrites its manifest at the end reuses the first one's).
    """
    argv = list(sys.argv if argv is None else argv)
    solvers = dict(solvers) if solvers is not None else solver_versions()
    data: dict[str, Any] = {
        "command": command,
        "argv": argv,
        "command_line": shlex.join(argv),
        "cwd": str(Path.cwd()),
        "created": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "python": platform.python_version(),
        "platform": platform.platform(),
        "packages": _importable_packages(package_versions(), solvers),
        "source": source_revision(),
        "solvers": solvers,
        "case_dir": str(case_dir) if case_dir is not None else None,
        "config_files": config_file_hashes(case_dir),
        "seeds": dict(seeds or {}),
        "settings": _jsonable(dict(settings or {})),
    }
    if extra:
        data.update(_jsonable(dict(extra)))
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    path = out / MANIFEST_NAME
    tmp = path.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(data, indent=2, sort_keys=False) + "\n")
    os.replace(tmp, path)
    return path


def read_manifest(run_dir: str | os.PathLike[str]) -> dict[str, Any]:
    return json.loads((Path(run_dir) / MANIFEST_NAME).read_text())


def _jsonable(value: Any) -> Any:
    """Settings as JSON: paths and other objects become strings."""
    if isinstance(value, Mapping):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    if hasattr(value, "item"):  # numpy scalars
        try:
            return value.item()
        except (TypeError, ValueError):
            pass
    return str(value)
