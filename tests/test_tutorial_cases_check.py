"""Every packaged tutorial case passes `gymprecice check` (configs + cross-check + plugins)."""

from __future__ import annotations

from pathlib import Path

import pytest

import gymprecice_tutorials
from gymprecice.tools.cli import main

PACKAGE = Path(gymprecice_tutorials.__file__).resolve().parent
CASES = sorted(p.parent for p in PACKAGE.rglob("gymprecice-config.json"))
NAMES = [c.relative_to(PACKAGE).as_posix() for c in CASES]


def test_every_tutorial_case_is_found() -> None:
    assert {
        "cases/jet_cylinder",
        "cases/rotating_cylinder",
        "cases/quickstart",
        "perpendicular_flap/case",
    } <= set(NAMES)


@pytest.mark.parametrize("case", CASES, ids=NAMES)
def test_case_passes_gymprecice_check(case: Path, capsys) -> None:
    assert main(["check", str(case)]) == 0, capsys.readouterr()
    out = capsys.readouterr().out
    assert "Controller" in out
