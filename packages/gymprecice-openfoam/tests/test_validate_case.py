"""`gymprecice check` on OpenFOAM cases: what would only fail (or silently not couple) at
run time is reported at load time, naming the file and the fix."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from gymprecice.testing.chaos import PRECICE_XML
from gymprecice.tools.cli import main
from gymprecice_openfoam import testing

BOUNDARY = testing.HEADER.format(cls="polyBoundaryMesh", obj="boundary") + (
    "3\n(\n"
    "    jet1 { type patch; nFaces 1; startFace 0; }\n"
    "    jet2 { type patch; nFaces 1; startFace 1; }\n"
    "    walls { type wall; nFaces 1; startFace 2; }\n"
    ")\n"
)
INTERFACES = {
    "Jet1": {"mesh": "Fluid-Mesh-jet1", "patches": ["jet1"], "read": ["Velocity"]},
    "Jet2": {"mesh": "Fluid-Mesh-jet2", "patches": ["jet2"], "read": ["Velocity"]},
}


def _case(root: Path, *, options: dict | None = None) -> Path:
    fluid = root / "fluid-openfoam"
    (fluid / "system").mkdir(parents=True)
    (fluid / "constant" / "polyMesh").mkdir(parents=True)
    (fluid / "system" / "controlDict").write_text(testing.control_dict())
    (fluid / "system" / "preciceDict").write_text(testing.precice_dict(INTERFACES))
    (fluid / "constant" / "polyMesh" / "boundary").write_text(BOUNDARY)
    (root / "precice-config.xml").write_text(PRECICE_XML.format(end_time=0.01, window=0.001))
    config = {
        "physics_simulation_engine": {
            "solvers": {
                "fluid": {
                    "kind": "openfoam",
                    "path": "fluid-openfoam",
                    "participant": "Fluid",
                    "options": options or {},
                }
            }
        },
        "controller": {"write_to": {"jet1": "Velocity", "jet2": "Velocity"}},
    }
    (root / "gymprecice-config.json").write_text(json.dumps(config))
    return root


def _edit(path: Path, old: str, new: str) -> None:
    text = path.read_text()
    assert old in text
    path.write_text(text.replace(old, new))


def _check(capsys, case: Path) -> tuple[int, str]:
    status = main(["check", str(case)])
    return status, capsys.readouterr().err


def test_a_good_case_passes(capsys, tmp_path: Path) -> None:
    status, err = _check(capsys, _case(tmp_path))
    assert status == 0, err


def test_no_adapter_in_control_dict(capsys, tmp_path: Path) -> None:
    case = _case(tmp_path)
    control = case / "fluid-openfoam" / "system" / "controlDict"
    control.write_text(testing.control_dict(adapter=False))
    status, err = _check(capsys, case)
    assert status == 1
    assert f"{control}: no preCICE adapter function object" in err
    assert "preciceAdapterFunctionObject" in err  # the snippet to paste


@pytest.mark.parametrize("switch", ["false", "off", "no"])
def test_a_disabled_adapter(capsys, tmp_path: Path, switch: str) -> None:
    case = _case(tmp_path)
    control = case / "fluid-openfoam" / "system" / "controlDict"
    _edit(
        control,
        "type preciceAdapterFunctionObject;",
        f"type preciceAdapterFunctionObject; enabled {switch};",
    )
    status, err = _check(capsys, case)
    assert status == 1
    assert f"{control}: the preCICE adapter entry 'preCICE_Adapter' has 'enabled false;'" in err


def test_a_mesh_name_absent_from_the_xml(capsys, tmp_path: Path) -> None:
    case = _case(tmp_path)
    pdict = case / "fluid-openfoam" / "system" / "preciceDict"
    _edit(pdict, "mesh Fluid-Mesh-jet1;", "mesh Fluid-Mesh-jetX;")
    status, err = _check(capsys, case)
    assert status == 1
    assert f"{pdict}: interface 'Jet1' uses mesh 'Fluid-Mesh-jetX'" in err
    assert str(case / "precice-config.xml") in err and "'Fluid-Mesh-jet1'" in err


def test_data_of_a_module_the_precice_dict_does_not_enable(capsys, tmp_path: Path) -> None:
    # A CHT fluid whose preciceDict lists only FF: the adapter would refuse the
    # temperature at run time, after the other participants have started.
    case = _case(tmp_path)
    pdict = case / "fluid-openfoam" / "system" / "preciceDict"
    _edit(pdict, "modules (FF);", "modules (FSI);")
    status, err = _check(capsys, case)
    assert status == 1
    assert f"{pdict}: interface 'Jet1' exchanges 'Velocity'" in err
    assert "adapter's FF module handles, but 'modules' is (FSI); add it: 'modules (FSI FF);'" in err


def test_adapter_modules_by_data_name() -> None:
    from gymprecice_openfoam.checks import adapter_module

    assert adapter_module("Temperature") == "CHT"
    assert adapter_module("Heat-Flux") == "CHT"
    assert adapter_module("FlowTemperature") == "FF"
    assert adapter_module("Velocity") == "FF"
    assert adapter_module("DisplacementDelta") == "FSI"
    assert adapter_module("Colour") is None


def test_a_patch_absent_from_the_boundary_file(capsys, tmp_path: Path) -> None:
    case = _case(tmp_path)
    pdict = case / "fluid-openfoam" / "system" / "preciceDict"
    _edit(pdict, "jet2\n", "jett2\n")
    status, err = _check(capsys, case)
    assert status == 1
    assert f"{pdict}: interface 'Jet2' names patch 'jett2'" in err
    assert "did you mean 'jet2'?" in err
    assert str(case / "fluid-openfoam" / "constant" / "polyMesh" / "boundary") in err


def test_a_patch_absent_from_the_block_mesh_dict_of_an_unbuilt_mesh(capsys, tmp_path) -> None:
    """No mesh yet: the patches blockMesh will make are read from its dictionary."""
    case = _case(tmp_path)
    fluid = case / "fluid-openfoam"
    (fluid / "constant" / "polyMesh" / "boundary").unlink()
    (fluid / "system" / "blockMeshDict").write_text(testing.cylinder_block_mesh_dict())
    status, err = _check(capsys, case)
    assert status == 0, err
    _edit(fluid / "system" / "preciceDict", "jet2\n", "jet3\n")
    status, err = _check(capsys, case)
    assert status == 1
    pdict = fluid / "system" / "preciceDict"
    assert f"{pdict}: interface 'Jet2' names patch 'jet3', which " in err
    assert f"{fluid / 'system' / 'blockMeshDict'} does not have (did you mean 'jet2'?)" in err


@pytest.mark.parametrize(
    ("participant", "message"),
    [
        ("Solid", "participant 'Solid' is not a participant of"),
        ("Controller", "the gymprecice configuration says this solver plays 'Fluid'"),
    ],
)
def test_a_wrong_participant(capsys, tmp_path: Path, participant: str, message: str) -> None:
    case = _case(tmp_path)
    pdict = case / "fluid-openfoam" / "system" / "preciceDict"
    _edit(pdict, "participant Fluid;", f"participant {participant};")
    status, err = _check(capsys, case)
    assert status == 1
    assert f"{pdict}:" in err and message in err and "participant Fluid;" in err


def test_a_precice_config_path_elsewhere(capsys, tmp_path: Path) -> None:
    case = _case(tmp_path)
    pdict = case / "fluid-openfoam" / "system" / "preciceDict"
    _edit(pdict, '"../precice-config.xml"', '"../other.xml"')
    status, err = _check(capsys, case)
    assert status == 1
    assert f"{pdict}: preciceConfig '../other.xml'" in err


def test_a_misspelled_plugin_option(capsys, tmp_path: Path) -> None:
    case = _case(tmp_path, options={"prerun_endtime": 0.1})
    status, err = _check(capsys, case)
    assert status == 1
    assert str(case / "gymprecice-config.json") in err
    assert "'prerun_endtime' (did you mean 'prerun_end_time'?)" in err


def test_geometry_of_a_mesh_preciceDict_does_not_use_names_both_meshes(tmp_path: Path) -> None:
    """At run time too: preciceDict's mesh names against the XML's, not 'call
    set_interface_vertices'."""
    from gymprecice.plugin.errors import CaseError
    from gymprecice.plugin.precice_xml import load_precice_config
    from gymprecice.plugin.solver import SolverContext
    from gymprecice_openfoam import plugin

    case = _case(tmp_path)
    pdict = case / "fluid-openfoam" / "system" / "preciceDict"
    _edit(pdict, "mesh Fluid-Mesh-jet1;", "mesh Fluid-Mesh-jetX;")
    solver = SolverContext(
        name="fluid",
        kind="openfoam",
        run_dir=case / "fluid-openfoam",
        source_dir=case / "fluid-openfoam",
        env_dir=case,
        participant="Fluid",
        precice=load_precice_config(case / "precice-config.xml"),
        precice_config_file=case / "precice-config.xml",
    )
    with pytest.raises(CaseError) as info:
        plugin.gymprecice_interface_geometry(
            solver=solver, interface="jet1", mesh="Fluid-Mesh-jet1"
        )
    message = str(info.value)
    assert message.startswith(f"{pdict}: participant 'Fluid' provides mesh 'Fluid-Mesh-jet1'")
    assert "'Fluid-Mesh-jetX'" in message
    # A mesh of another participant is not this case's to describe.
    assert (
        plugin.gymprecice_interface_geometry(
            solver=solver, interface="jet1", mesh="Controller-Mesh-jet1"
        )
        is None
    )


def _tutorial_block_mesh_dicts() -> list[bytes]:
    """Every blockMeshDict the tutorials ship or write, and the test case's."""
    root = Path(__file__).resolve().parents[2] / "gymprecice-tutorials" / "src"
    found = [p.read_bytes() for p in sorted(root.rglob("blockMeshDict"))]
    return [*found, testing.cylinder_block_mesh_dict().encode()]


def test_block_mesh_patch_names_reads_every_patch_of_the_shipped_cases() -> None:
    """The names in file order, as blockMesh makes the patches (foamlib, which the check
    used before, takes tens of seconds on these files: their blocks)."""
    from gymprecice_openfoam.checks import block_mesh_patch_names

    texts = _tutorial_block_mesh_dicts()
    assert block_mesh_patch_names(texts[-1]) == [
        "inlet", "outlet", "walls", "cylinder", "jet1", "jet2", "frontAndBack"
    ]  # fmt: skip
    for data in texts:
        names = block_mesh_patch_names(data)
        assert names and len(set(names)) == len(names)
        assert all(f"{name}\n" in data.decode() or f"{name} " in data.decode() for name in names)


@pytest.mark.parametrize(
    ("text", "names"),
    [
        (b"boundary ( inlet { type patch; faces ((0 1 2 3)); } wall {} );", ["inlet", "wall"]),
        (b"// boundary ( fake {} );\nboundary ( /* old {} */ real { type wall; } );", ["real"]),
        (b'boundary ( #include "patches" );', None),  # only blockMesh expands it
        (b"patches ( patch inlet ((0 1 2 3)) );", None),  # old style: blockMesh will tell
        (b"FoamFile { object blockMeshDict; } boundary ();", []),
        (b"boundary ( inlet { type patch; ", None),  # unbalanced
    ],
)
def test_block_mesh_patch_names_reads_only_a_top_level_boundary_list(text, names) -> None:
    from gymprecice_openfoam.checks import block_mesh_patch_names

    assert block_mesh_patch_names(text) == names
