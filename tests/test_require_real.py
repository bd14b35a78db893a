"""GYMPRECICE_REQUIRE_REAL=1 (CI) turns a skipped real-stack test into a failure."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

TESTS = """
import pytest

@pytest.mark.precice
def test_real():
    pytest.skip("pyprecice is not installed")

def test_plain_skip():
    pytest.skip("nothing to do with the real stack")
"""


def _pytest(tmp_path: Path, require: str | None) -> subprocess.CompletedProcess[str]:
    shutil.copy(ROOT / "conftest.py", tmp_path / "conftest.py")
    (tmp_path / "test_sample.py").write_text(TESTS)
    (tmp_path / "pytest.ini").write_text("[pytest]\nmarkers =\n    precice: real preCICE\n")
    env = {k: v for k, v in os.environ.items() if k != "GYMPRECICE_REQUIRE_REAL"}
    if require is not None:
        env["GYMPRECICE_REQUIRE_REAL"] = require
    return subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", str(tmp_path)],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )


def test_skips_of_real_stack_tests_fail_when_required(tmp_path: Path) -> None:
    run = _pytest(tmp_path, "1")
    assert run.returncode == 1, run.stdout
    assert "1 failed, 1 skipped" in run.stdout
    assert "GYMPRECICE_REQUIRE_REAL=1 and this precice test was skipped" in run.stdout
    assert "pyprecice is not installed" in run.stdout


def test_skips_stay_skips_otherwise(tmp_path: Path) -> None:
    for require in (None, "0"):
        run = _pytest(tmp_path, require)
        assert run.returncode == 0 and "2 skipped" in run.stdout, run.stdout
