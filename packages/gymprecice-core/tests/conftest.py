"""Shared fixtures of core's tests: small, valid case directories written per test."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

PRECICE_XML = """<?xml version="1.0" encoding="UTF-8" ?>
<precice-configuration>
  <!-- a controller driving two jets of a 2-D fluid solver -->
  <data:vector name="Velocity" />
  <data:scalar name="Pressure" />
  <mesh name="Controller-Mesh-jet1" dimensions="2"><use-data name="Velocity" /></mesh>
  <mesh name="Controller-Mesh-jet2" dimensions="2"><use-data name="Velocity" /></mesh>
  <mesh name="Controller-Mesh-probe" dimensions="2"><use-data name="Pressure" /></mesh>
  <mesh name="Fluid-Mesh-jet1" dimensions="2"><use-data name="Velocity" /></mesh>
  <mesh name="Fluid-Mesh-jet2" dimensions="2"><use-data name="Velocity" /></mesh>
  <mesh name="Fluid-Mesh-probe" dimensions="2"><use-data name="Pressure" /></mesh>
  <participant name="Controller">
    <provide-mesh name="Controller-Mesh-jet1" />
    <provide-mesh name="Controller-Mesh-jet2" />
    <provide-mesh name="Controller-Mesh-probe" />
    <receive-mesh name="Fluid-Mesh-probe" from="Fluid" />
    <write-data name="Velocity" mesh="Controller-Mesh-jet1" />
    <write-data name="Velocity" mesh="Controller-Mesh-jet2" />
    <read-data name="Pressure" mesh="Controller-Mesh-probe" />
    <mapping:nearest-neighbor direction="read" from="Fluid-Mesh-probe" to="Controller-Mesh-probe" constraint="consistent" />
  </participant>
  <participant name="Fluid">
    <provide-mesh name="Fluid-Mesh-jet1" />
    <provide-mesh name="Fluid-Mesh-jet2" />
    <provide-mesh name="Fluid-Mesh-probe" />
    <receive-mesh name="Controller-Mesh-jet1" from="Controller" />
    <receive-mesh name="Controller-Mesh-jet2" from="Controller" />
    <read-data name="Velocity" mesh="Fluid-Mesh-jet1" />
    <read-data name="Velocity" mesh="Fluid-Mesh-jet2" />
    <write-data name="Pressure" mesh="Fluid-Mesh-probe" />
    <mapping:nearest-neighbor direction="read" from="Controller-Mesh-jet1" to="Fluid-Mesh-jet1" constraint="consistent" />
    <mapping:nearest-neighbor direction="read" from="Controller-Mesh-jet2" to="Fluid-Mesh-jet2" constraint="consistent" />
  </participant>
  <m2n:sockets acceptor="Controller" connector="Fluid" exchange-directory=".." />
  <coupling-scheme:parallel-explicit>
    <participants first="Controller" second="Fluid" />
    <max-time value="0.01" />
    <time-window-size value="0.001" />
    <exchange data="Velocity" mesh="Controller-Mesh-jet1" from="Controller" to="Fluid" />
    <exchange data="Velocity" mesh="Controller-Mesh-jet2" from="Controller" to="Fluid" />
    <exchange data="Pressure" mesh="Fluid-Mesh-probe" from="Fluid" to="Controller" />
  </coupling-scheme:parallel-explicit>
</precice-configuration>
"""


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
