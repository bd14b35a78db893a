"""The CI version of the Schäfer-Turek validation: a short real pimpleFoam run."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = [
    pytest.mark.openfoam,
    pytest.mark.slow,
    pytest.mark.skipif(shutil.which("pimpleFoam") is None, reason="OpenFOAM is not on PATH"),
]


@pytest.mark.timeout(900)
def test_smoke_validation_sheds_with_real_openfoam(tmp_path: Path) -> None:
    """Cost: about 60 CPU-s, one of the heaviest real tests (pimpleFoam on the coarse Schaefer-
    Turek mesh long enough to shed, which is what it checks).
    """
    figure = tmp_path / "validation.png"
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "gymprecice_tutorials.validate",
            "--smoke",
            "--out",
            str(tmp_path / "run"),
            "--figure",
            str(figure),
        ],
        capture_output=True,
        text=True,
        timeout=850,
    )
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    assert "Cd_max" in done.stdout and "St" in done.stdout
    assert figure.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
