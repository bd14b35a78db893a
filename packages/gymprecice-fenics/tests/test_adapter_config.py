"""fenicsprecice's adapter file against the preCICE XML: each mismatch named with its fix."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from gymprecice.plugin.errors import CaseError
from gymprecice.plugin.precice_xml import load_precice_config
from gymprecice_fenics.adapter_config import AdapterConfig, check_against_precice


def _edit(path: Path, **interface) -> None:
    raw = json.loads(path.read_text())
    for key, value in interface.items():
        if key == "participant_name":
            raw[key] = value
        elif value is None:
            raw["interface"].pop(key, None)
        else:
            raw["interface"][key] = value
    path.write_text(json.dumps(raw))


def _problems(case: Path, solver_participant: str | None = "Solid") -> list[str]:
    adapter = AdapterConfig.read(case / "solid-fenics" / "precice-adapter-config.json")
    cfg = load_precice_config(case / "precice-config.xml")
    return check_against_precice(adapter, cfg, solver_participant, "gymprecice-config.json")


def test_the_plate_case_agrees_with_its_xml(case: Path) -> None:
    assert _problems(case) == []


@pytest.mark.parametrize(
    ("edit", "needle"),
    [
        ({"participant_name": "Plate"}, "participant_name is 'Plate'"),
        ({"coupling_mesh_name": "Plate-Mesh"}, "coupling_mesh_name is 'Plate-Mesh'"),
        ({"read_data_name": "Heat-Flux"}, "read_data_name is 'Heat-Flux'"),
        ({"write_data_name": "Temperature"}, "write_data_name is 'Temperature'"),
        ({"write_data_name": None}, "write_data_name is not set"),
    ],
)
def test_a_name_the_xml_does_not_have_is_reported_with_both_files(
    case: Path, edit: dict, needle: str
) -> None:
    _edit(case / "solid-fenics" / "precice-adapter-config.json", **edit)
    problems = _problems(case, solver_participant=None)
    assert len(problems) == 1
    assert needle in problems[0]
    assert "precice-adapter-config.json" in problems[0]
    assert "precice-config.xml" in problems[0]


def test_solver_participant_must_match_the_adapter_file(case: Path) -> None:
    (problem,) = _problems(case, solver_participant="Plate")
    assert "'Solid'" in problem and "'Plate'" in problem and "gymprecice-config.json" in problem


def test_a_partner_writing_another_datum_than_the_script_reads_is_named(case: Path) -> None:
    # The XML lets the solid read Heat-Flux (so the names agree), but its partner sends
    # Temperature: the script would wait for data nobody writes.
    xml = case / "precice-config.xml"
    text = xml.read_text()
    text = text.replace(
        '<read-data name="Temperature" mesh="Solid-Mesh" />',
        '<read-data name="Temperature" mesh="Solid-Mesh" />\n'
        '    <read-data name="Heat-Flux" mesh="Solid-Mesh" />',
    )
    xml.write_text(text)
    _edit(case / "solid-fenics" / "precice-adapter-config.json", read_data_name="Heat-Flux")
    problems = _problems(case)
    assert any("reads 'Heat-Flux'" in p and "'Temperature' from 'Fluid'" in p for p in problems), (
        problems
    )


def test_missing_and_broken_files_say_what_to_do(tmp_path: Path) -> None:
    with pytest.raises(CaseError, match=r"does not exist.*options\.adapter_config"):
        AdapterConfig.read(tmp_path / "precice-adapter-config.json")
    broken = tmp_path / "broken.json"
    broken.write_text("{")
    with pytest.raises(CaseError, match="not valid JSON"):
        AdapterConfig.read(broken)
    broken.write_text(json.dumps({"participant_name": "Solid", "interface": {}}))
    with pytest.raises(CaseError, match="config_file_name"):
        AdapterConfig.read(broken)


def test_point_at_writes_a_path_relative_to_the_adapter_file(case: Path, tmp_path: Path) -> None:
    path = case / "solid-fenics" / "precice-adapter-config.json"
    adapter = AdapterConfig.read(path)
    target = tmp_path / "env" / "precice-config.xml"
    target.parent.mkdir()
    target.write_text("")
    assert adapter.point_at(target) is True
    written = json.loads(path.read_text())
    assert (path.parent / written["config_file_name"]).resolve() == target.resolve()
    assert written["interface"]["read_data_name"] == "Temperature"  # the rest is kept
    assert AdapterConfig.read(path).point_at(target) is False
