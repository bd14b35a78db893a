"""Fixtures shared by the tutorials' tests."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest


@pytest.fixture
def gymprecice_cli() -> Callable[..., str]:
    """``gymprecice ARGS`` as a user types it, in ``cwd``: its output, or a failed test
    showing both streams."""

    def run(cwd: Path, *args: str) -> str:
        proc = subprocess.run(
            [sys.executable, "-m", "gymprecice", *args],
            cwd=cwd,
            capture_output=True,
            text=True,
            timeout=300,
        )
        assert proc.returncode == 0, f"exit {proc.returncode}\n{proc.stdout}\n{proc.stderr}"
        return proc.stdout + proc.stderr

    return run
