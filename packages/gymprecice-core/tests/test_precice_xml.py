from __future__ import annotations

from pathlib import Path

import pytest

from gymprecice.plugin.errors import ConfigError
from gymprecice.plugin.precice_xml import load_precice_config, write_with_exchange_directory


def test_reads_prefixed_tags_meshes_data_and_scheme(case_dir: Path) -> None:
    cfg = load_precice_config(case_dir / "precice-config.xml")
    assert cfg.data["Velocity"].kind == "vector"
    assert cfg.data["Pressure"].kind == "scalar"
    assert cfg.meshes["Controller-Mesh-jet1"].dimensions == 2
    controller = cfg.participant("Controller")
    assert controller.provided_meshes == [
        "Controller-Mesh-jet1",
        "Controller-Mesh-jet2",
        "Controller-Mesh-probe",
    ]
    assert ("Velocity", "Controller-Mesh-jet1") in controller.write_data
    assert controller.received_meshes == {"Fluid-Mesh-probe": "Fluid"}
    (scheme,) = cfg.coupling_schemes
    assert scheme.kind == "parallel-explicit" and not scheme.implicit
    assert (scheme.first, scheme.second) == ("Controller", "Fluid")
    assert cfg.end_time("Controller") == pytest.approx(0.01)
    assert cfg.time_window_size("Controller") == pytest.approx(0.001)
    assert cfg.data_dimension("Velocity", "Controller-Mesh-jet1") == 2
    assert cfg.data_dimension("Pressure", "Controller-Mesh-probe") == 1
    assert cfg.m2n[0].acceptor == "Controller" and cfg.m2n[0].connector == "Fluid"


def test_mapped_partner_mesh_follows_the_mapping(case_dir: Path) -> None:
    cfg = load_precice_config(case_dir / "precice-config.xml")
    assert cfg.mapped_partner_mesh("Controller-Mesh-jet2") == ("Fluid", "Fluid-Mesh-jet2")


def test_multi_scheme_and_max_time_windows(tmp_path: Path, precice_xml: str) -> None:
    xml = precice_xml.replace(
        '<coupling-scheme:parallel-explicit>\n    <participants first="Controller" second="Fluid" />',
        '<coupling-scheme:multi>\n    <participant name="Fluid" control="yes" />\n    <participant name="Controller" />',
    ).replace(
        "</coupling-scheme:parallel-explicit>",
        '<max-iterations value="5" /></coupling-scheme:multi>',
    )
    xml = xml.replace('<max-time value="0.01" />', '<max-time-windows value="20" />')
    path = tmp_path / "p.xml"
    path.write_text(xml)
    cfg = load_precice_config(path)
    (scheme,) = cfg.coupling_schemes
    assert scheme.kind == "multi" and scheme.control == "Fluid" and scheme.implicit
    assert scheme.max_iterations == 5
    assert cfg.end_time("Controller") == pytest.approx(0.02)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (
            ('<mesh name="Fluid-Mesh-jet1" dimensions="2">', '<mesh name="Fluid-Mesh-jet1">'),
            "dimensions",
        ),
        (('<participants first="Controller"', '<participants first="Nobody"'), "Nobody"),
        (("</precice-configuration>", "<oops></precice-configuration>"), "not well-formed"),
        (
            (
                '<provide-mesh name="Fluid-Mesh-jet1" />',
                '<use-mesh name="Fluid-Mesh-jet1" provide="yes" />',
            ),
            "v2",
        ),
        (
            (
                '<read-data name="Pressure" mesh="Controller-Mesh-probe" />',
                '<read-data name="Pressure" mesh="Controller-Mesh-jet1" />',
            ),
            "use-data",
        ),
    ],
)
def test_bad_files_name_the_file_and_problem(
    tmp_path: Path, precice_xml: str, change, message
) -> None:
    path = tmp_path / "precice-config.xml"
    path.write_text(precice_xml.replace(*change))
    with pytest.raises(ConfigError, match=message) as info:
        load_precice_config(path)
    assert str(path) in str(info.value)


def test_v2_solver_interface_is_refused_with_advice(tmp_path: Path) -> None:
    path = tmp_path / "old.xml"
    path.write_text(
        '<precice-configuration><solver-interface dimensions="2"/></precice-configuration>'
    )
    with pytest.raises(ConfigError, match="preCICE v2"):
        load_precice_config(path)


def test_exchange_directory_rewrite_keeps_everything_else(case_dir: Path, tmp_path: Path) -> None:
    source = case_dir / "precice-config.xml"
    source.write_text(
        source.read_text().replace(
            "<precice-configuration>",
            "<precice-configuration>\n  <!-- a controller driving two jets -->",
        )
    )
    target = tmp_path / "copy.xml"
    write_with_exchange_directory(source, target, tmp_path / "xchg")
    text = target.read_text()
    assert f'exchange-directory="{tmp_path / "xchg"}"' in text
    assert "<!-- a controller driving two jets" in text
    assert "<coupling-scheme:parallel-explicit>" in text
    reread = load_precice_config(target)
    assert reread.m2n[0].exchange_directory == str(tmp_path / "xchg")
    assert (
        reread.participants.keys()
        == load_precice_config(case_dir / "precice-config.xml").participants.keys()
    )


def test_partner_of_a_mesh_the_controller_maps_itself_is_the_other_participant(
    case_dir: Path, tmp_path: Path, precice_xml: str
) -> None:
    """The controller's own read mapping (Fluid-Mesh-probe -> Controller-Mesh-probe) must
    not make the controller its own partner."""
    cfg = load_precice_config(case_dir / "precice-config.xml")
    assert cfg.mapped_partner_mesh("Controller-Mesh-probe") == ("Fluid", "Fluid-Mesh-probe")
    # A controller that maps before the solver does, for a mesh both of them map.
    xml = precice_xml.replace(
        '<mapping:nearest-neighbor direction="read" from="Fluid-Mesh-probe"',
        '<receive-mesh name="Fluid-Mesh-jet1" from="Fluid" />\n    '
        '<mapping:nearest-neighbor direction="write" from="Controller-Mesh-jet1" '
        'to="Fluid-Mesh-jet1" constraint="consistent" />\n    '
        '<mapping:nearest-neighbor direction="read" from="Fluid-Mesh-probe"',
    )
    path = tmp_path / "controller-maps.xml"
    path.write_text(xml)
    cfg = load_precice_config(path)
    assert cfg.mapped_partner_mesh("Controller-Mesh-jet1") == ("Fluid", "Fluid-Mesh-jet1")
    assert cfg.mapped_partner_mesh("Controller-Mesh-probe") == ("Fluid", "Fluid-Mesh-probe")


@pytest.mark.parametrize("junk", ["<oops", "garbage", "<data:vector name='X' />"])
def test_junk_after_the_root_element_is_refused(tmp_path: Path, precice_xml: str, junk) -> None:
    """preCICE refuses such a file; lxml's recovery mode would silently drop the junk."""
    path = tmp_path / "precice-config.xml"
    path.write_text(precice_xml + junk)
    with pytest.raises(ConfigError, match="junk after document element") as info:
        load_precice_config(path)
    assert f"{path}:43:" in str(info.value) and "</precice-configuration>" in str(info.value)
    with pytest.raises(ConfigError, match="junk after document element"):
        write_with_exchange_directory(path, tmp_path / "copy.xml", tmp_path / "xchg")


def test_comments_after_the_root_element_are_fine(tmp_path: Path, precice_xml: str) -> None:
    path = tmp_path / "precice-config.xml"
    path.write_text(precice_xml + "<!-- trailing note -->\n\n")
    assert "Controller" in load_precice_config(path).participants
