"""Test-wide settings for every test directory of the repository."""

from __future__ import annotations

from pathlib import Path

import pytest


@pytest.fixture(autouse=True)
def _private_prerun_cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Each test its own OpenFOAM pre-run cache: none reads another's or the user's."""
    monkeypatch.setenv("GYMPRECICE_CACHE_DIR", str(tmp_path / "gymprecice-cache"))
