"""Puts a new package's files on disk without overwriting what is there: an existing
folder is refused (:class:`Exists`) unless ``force``, and even then only the package's own
files are replaced; the files are written in a staging folder first, so a failure leaves
no half-made package.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

__all__ = ["Exists", "write_package"]


class Exists(ValueError):
    """The target folder is there already and ``--force`` was not given: exit status 1."""


def write_package(target: Path, files: dict[str, str], force: bool = False) -> list[Path]:
    """Write ``files`` under ``target``; :class:`Exists` when ``target`` holds anything
    and ``force`` is false. Written in a staging folder beside it first, so a failure
    leaves no half-made package."""
    if target.exists() and not target.is_dir():
        raise Exists(f"{target} exists and is not a folder")
    if target.is_dir() and any(target.iterdir()) and not force:
        raise Exists(
            f"{target} exists; pass --force to overwrite the new package's files there "
            "(other files are left alone)"
        )
    target.parent.mkdir(parents=True, exist_ok=True)
    stage = Path(tempfile.mkdtemp(prefix=f".{target.name}-new-", dir=target.parent))
    try:
        for relative, text in files.items():
            path = stage / relative
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(text)
        if not target.exists():
            stage.rename(target)
        else:
            for relative in files:
                (target / relative).parent.mkdir(parents=True, exist_ok=True)
                os.replace(stage / relative, target / relative)
    finally:
        shutil.rmtree(stage, ignore_errors=True)
    return [target / relative for relative in files]
