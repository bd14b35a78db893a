"""Shared fixtures of core's tests: small, valid case directories written per test."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from gymprecice.testing.chaos import PRECICE_XML as CHAOS_XML

#: Controller + Fluid, two jets and a probe mesh, parallel-explicit, ten 1 ms windows.
PRECICE_XML = CHAOS_XML.format(end_time=0.01, window=0.001)


def explicit_config(**overrides) -> dict:
    config = {
        "environment": {"name": "jets"},
        "precice": {"config_file": "precice-config.xml"},
        "physics_simulation_engine": {
            "solvers": {
                "fluid": {
                    "kind": "command",
                    "path": "fluid",
                    "participant": "Fluid",
                    "options": {"argv": ["{python}", "-c", "pass"]},
                }
            }
        },
        "controller": {
            "participant": "Controller",
            "write_to": {"jet1": "Velocity", "jet2": "Velocity"},
            "read_from": {"probe": "Pressure"},
        },
    }
    config.update(overrides)
    return config


def write_case(root: Path, config: dict | None = None, xml: str = PRECICE_XML) -> Path:
    root.mkdir(parents=True, exist_ok=True)
    (root / "precice-config.xml").write_text(xml)
    (root / "fluid").mkdir(exist_ok=True)
    (root / "fluid" / "input.txt").write_text("pristine\n")
    (root / "gymprecice-config.json").write_text(json.dumps(config or explicit_config(), indent=2))
    return root


@pytest.fixture
def case_dir(tmp_path: Path) -> Path:
    return write_case(tmp_path / "case")


@pytest.fixture
def precice_xml() -> str:
    return PRECICE_XML


@pytest.fixture
def make_case():
    """Factory: ``make_case(root, config=None, xml=PRECICE_XML)`` writes a case directory."""
    return write_case


@pytest.fixture
def base_config():
    """Factory for the explicit-form config dict of the default test case."""
    return explicit_config
