"""Which installed distribution provides the ``gymprecice`` import package, and the clash.

gymprecice-core installs the import package ``gymprecice``. A different, older distribution
on the public index is *named* ``gymprecice`` and installs the same import package: installed
after gymprecice-core it silently overwrites ``gymprecice/__init__.py``; uninstalled, it
deletes that file and leaves gymprecice-core broken. Nothing in pip warns about it, so
``gymprecice doctor`` looks for it here, from the installed metadata only (no import of the
other package, which may not work):

* a distribution named ``gymprecice`` is installed;
* another distribution than gymprecice-core lists ``gymprecice/__init__.py`` in its files;
* the ``gymprecice/__init__.py`` that Python imports is missing or differs from the one
  gymprecice-core's own record lists (overwritten, or deleted by the other's uninstall).

The fix is the same in every case: uninstall the other distribution, then reinstall
gymprecice-core so its files are whole again.
"""

from __future__ import annotations

import base64
import hashlib
import re
from importlib import metadata
from pathlib import Path

__all__ = ["CLASH_FIX", "CORE_DISTRIBUTION", "core_version", "name_clash"]

CORE_DISTRIBUTION = "gymprecice-core"
CLASH_FIX = "pip uninstall gymprecice, then pip install --force-reinstall gymprecice-core"
_INIT = "gymprecice/__init__.py"


def _normalise(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


def core_version() -> str:
    """gymprecice-core's version, from its metadata (an overwritten ``__init__.py`` may lie)."""
    try:
        return metadata.version(CORE_DISTRIBUTION)
    except metadata.PackageNotFoundError:
        pass
    try:  # a source tree on sys.path, not installed
        from gymprecice import __version__ as version
    except ImportError:
        return "unknown"
    return str(version)


def _lists_init(dist: metadata.Distribution) -> bool:
    """Whether ``dist`` installs ``gymprecice/__init__.py`` (its RECORD, or an egg's list)."""
    for record in ("RECORD", "SOURCES.txt", "installed-files.txt"):
        text = dist.read_text(record)
        if text and re.search(r"(^|[/\\])gymprecice/__init__\.py([,\s]|$)", text, re.MULTILINE):
            return True
    return False


def _recorded_hash(dist: metadata.Distribution) -> str | None:
    """The ``sha256=...`` gymprecice-core's RECORD gives its ``__init__.py`` (None: editable)."""
    for line in (dist.read_text("RECORD") or "").splitlines():
        path, _, rest = line.partition(",")
        if path == _INIT:
            return rest.split(",", 1)[0] or None
    return None


def _file_hash(path: Path) -> str:
    digest = hashlib.sha256(path.read_bytes()).digest()
    return "sha256=" + base64.urlsafe_b64encode(digest).rstrip(b"=").decode()


def name_clash(package_dirs: list[str] | None = None) -> str | None:
    """What is wrong with who owns the ``gymprecice`` package, or ``None`` when nothing is.

    ``package_dirs`` are the directories of the imported ``gymprecice`` package (its
    ``__path__``; read from the import system when ``None``).
    """
    others: list[str] = []
    core: metadata.Distribution | None = None
    for dist in metadata.distributions():
        name = dist.metadata["Name"] or ""
        if _normalise(name) == CORE_DISTRIBUTION:
            core = core or dist
        elif _normalise(name) == "gymprecice" or _lists_init(dist):
            others.append(f"{name} {dist.version}")
    others = list(dict.fromkeys(others))
    if others:
        return (
            f"another distribution installs the gymprecice package: {', '.join(others)} "
            "(not gymprecice-core; it overwrites gymprecice/__init__.py, and uninstalling it "
            "later deletes that file)"
        )
    if core is None:
        return None  # run from a source tree: nothing installed to compare with
    expected = _recorded_hash(core)
    if expected is None:
        return None  # an editable install: its files are the source tree itself
    if package_dirs is None:
        import gymprecice

        package_dirs = list(getattr(gymprecice, "__path__", []))
    inits = [Path(d) / "__init__.py" for d in package_dirs]
    present = [p for p in inits if p.is_file()]
    if not present:
        return (
            "gymprecice/__init__.py is missing (deleted when another distribution named "
            "gymprecice was uninstalled)"
        )
    if all(_file_hash(p) != expected for p in present):
        return (
            f"{present[0]} is not the file gymprecice-core installed (overwritten by another "
            "distribution named gymprecice)"
        )
    return None
