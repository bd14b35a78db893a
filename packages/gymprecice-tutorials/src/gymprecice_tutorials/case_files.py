"""Write a generated case once, under a name that changes whenever its content does.

Every tutorial that shapes a packaged case at run time (the cylinder recipes, the flap's
training case) writes the files here. The directory is named after a hash of every file,
so identical cases share one directory and a changed case never reuses a stale one. It is
written to a temporary directory and renamed into place, so many environments (one per
process of a vector env) can ask for the same case at once without a lock.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import tempfile
from collections.abc import Iterable, Mapping, MutableMapping
from pathlib import Path

__all__ = ["apply_edits", "write_case_files"]


def write_case_files(name: str, files: Mapping[str, str], root: str | Path | None = None) -> Path:
    """Write ``files`` (relative path -> text) to ``<root>/cases/<name>-<hash>/`` once.

    ``root`` defaults to ``gymprecice-runs`` in the working directory. A file whose text
    starts with ``#!`` is made executable. Returns the case directory.
    """
    base = Path(root) if root is not None else Path("gymprecice-runs")
    if not base.is_absolute():
        base = Path.cwd() / base
    cases = base / "cases"
    digest = hashlib.sha256()
    for rel in sorted(files):
        digest.update(rel.encode() + b"\0" + files[rel].encode() + b"\0")
    target = cases / f"{name}-{digest.hexdigest()[:12]}"
    if (target / "gymprecice-config.json").is_file():
        return target
    cases.mkdir(parents=True, exist_ok=True)
    scratch = Path(tempfile.mkdtemp(prefix=f".{target.name}-", dir=cases))
    try:
        for rel, text in files.items():
            path = scratch / rel
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(text)
            if text.startswith("#!"):
                path.chmod(0o755)
        try:
            os.rename(scratch, target)
        except OSError:
            if not (target / "gymprecice-config.json").is_file():  # not a lost race: real error
                raise
    finally:
        if scratch.exists():
            shutil.rmtree(scratch, ignore_errors=True)
    return target


def apply_edits(
    files: MutableMapping[str, str],
    edits: Iterable[tuple[str, str, str]],
    case_dir: Path,
    module: str,
    table: str = "FAST_EDITS",
) -> None:
    """Replace, in place, each edit's ``old`` text in ``files[rel]`` by ``new``.

    Each ``(rel, old, new)`` must match exactly once, so a packaged case that changed
    under a tutorial fails loudly here, naming the file and the edits' ``table`` in
    ``module`` to update, rather than running a case half edited.
    """
    for rel, old, new in edits:
        count = files[rel].count(old)
        if count != 1:
            raise ValueError(
                f"{case_dir / rel}: the edits of {table} change {old!r}, which occurs {count} "
                f"times (expected once); update {table} in {module} to the packaged case"
            )
        files[rel] = files[rel].replace(old, new)
