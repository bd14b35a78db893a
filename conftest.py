"""Test-wide settings for every test directory of the repository."""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import pytest

#: Set to 1 (CI does) to turn a skipped real-stack test into a failure: where the set-up
#: builds preCICE and the adapters, a ``precice``/``openfoam``/``dealii``/``fenics`` test that skips
#: proves nothing and hides a broken set-up.
REQUIRE_REAL_ENV = "GYMPRECICE_REQUIRE_REAL"
REAL_MARKERS = ("precice", "openfoam", "dealii", "fenics")


@pytest.fixture(autouse=True)
def _private_prerun_cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Each test its own OpenFOAM pre-run cache: none reads another's or the user's."""
    monkeypatch.setenv("GYMPRECICE_CACHE_DIR", str(tmp_path / "gymprecice-cache"))


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo) -> Iterator[None]:
    outcome = yield
    report = outcome.get_result()
    if not report.skipped or os.environ.get(REQUIRE_REAL_ENV, "0") in ("", "0"):
        return
    markers = [m for m in REAL_MARKERS if item.get_closest_marker(m) is not None]
    if not markers:
        return
    reason = report.longrepr[2] if isinstance(report.longrepr, tuple) else str(report.longrepr)
    report.outcome = "failed"
    report.longrepr = (
        f"{REQUIRE_REAL_ENV}=1 and this {'/'.join(markers)} test was skipped ({reason}); "
        "the set-up did not provide the real stack: see `gymprecice doctor` and "
        "`gymprecice install --list`"
    )
