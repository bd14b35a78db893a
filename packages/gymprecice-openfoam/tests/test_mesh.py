"""Patch geometry against OpenFOAM's own face centres, and preciceDict interfaces.

The reference is ``postProcess -func writeCellCentres``: the boundary values of the ``C``
field it writes are OpenFOAM's patch face centres (what the preCICE adapter sends).
Meshes are warped, polygonal, binary, compressed and decomposed so each reading path
and the centroid formula itself are exercised; a vertex average would be off by ~1e-3.
"""

from __future__ import annotations

import gzip
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from foamlib import FoamFieldFile, FoamFile

from gymprecice.plugin.errors import CaseError
from gymprecice_openfoam import mesh, testing

WARPED_BLOCK = (
    testing.HEADER.format(cls="dictionary", obj="blockMeshDict")
    + """scale 1;
vertices ( (0 0 0) (1.1 0 0.05) (1 1 -0.1) (0 1.2 0.1) (0 0 1) (1 0.1 1.2) (1.1 1 1) (-0.1 1 0.9) );
blocks ( hex (0 1 2 3 4 5 6 7) (3 3 2) simpleGrading (1 2 0.5) );
edges ();
boundary (
  xmin { type wall; faces ( (0 4 7 3) ); }
  xmax { type wall; faces ( (1 2 6 5) ); }
  ymin { type patch; faces ( (0 1 5 4) ); }
  ymax { type patch; faces ( (3 7 6 2) ); }
  zmin { type wall; faces ( (0 3 2 1) ); }
  zmax { type wall; faces ( (4 5 6 7) ); }
);
"""
)
WARPED_PATCHES = {
    "xmin": "wall",
    "xmax": "wall",
    "ymin": "wall",
    "ymax": "wall",
    "zmin": "wall",
    "zmax": "wall",
}


def _reference(case: Path, time: str = "0") -> FoamFieldFile:
    return FoamFieldFile(case / time / "C")


def _check_against_openfoam(case: Path, patches: list[str], time: str = "0") -> int:
    ref = _reference(case, time)
    mesh.clear_cache()
    geoms = mesh.patch_geometry(case / "constant" / "polyMesh", patches)
    faces = 0
    for g in geoms:
        expected = np.asarray(ref.boundary_field[g.name]["value"], dtype=float)
        assert g.centres.shape == expected.shape
        np.testing.assert_allclose(g.centres, expected, rtol=0, atol=1e-10)
        faces += len(g.centres)
    return faces


def _warped_case(tmp_path: Path, name: str, *, fmt: str = "ascii") -> Path:
    return testing.write_flow_case(
        tmp_path / name,
        WARPED_BLOCK,
        WARPED_PATCHES,
        write_format=fmt,
        write_precision=17,
        adapter=False,
    )


@pytest.mark.openfoam
@pytest.mark.parametrize("fmt", ["ascii", "binary"])
def test_face_centres_match_openfoam_on_warped_hexes(tmp_path, run, fmt):
    """Cost: under a second (blockMesh and postProcess of a few warped hexes)."""
    case = _warped_case(tmp_path, fmt, fmt=fmt)
    run(case, "blockMesh")
    run(case, "postProcess", "-func", "writeCellCentres", "-time", "0")
    faces = _check_against_openfoam(case, list(WARPED_PATCHES))
    assert faces == 2 * (9 + 6 + 6)
    header = (case / "constant" / "polyMesh" / "faces").read_bytes()[:1000]
    assert f"format      {fmt}".encode() in header


@pytest.mark.openfoam
def test_face_centres_match_openfoam_on_polygons_and_gzip(tmp_path, run):
    """polyDualMesh makes 4-, 5- and 6-gons; gzip-compressed mesh files are read too.

    Cost: under a second (blockMesh, polyDualMesh, postProcess).
    """
    case = _warped_case(tmp_path, "dual")
    run(case, "blockMesh")
    run(case, "polyDualMesh", "-overwrite", "60")
    mesh_dir = case / "constant" / "polyMesh"
    for name in ("points", "faces", "owner", "neighbour", "boundary"):
        path = mesh_dir / name
        path.with_name(name + ".gz").write_bytes(gzip.compress(path.read_bytes()))
        path.unlink()
    # OpenFOAM reads the compressed mesh, so its centres refer to the same files.
    run(case, "postProcess", "-func", "writeCellCentres", "-time", "0")
    mesh.clear_cache()
    geoms = mesh.patch_geometry(mesh_dir, list(WARPED_PATCHES))
    sizes = np.concatenate([np.diff(g.offsets) for g in geoms])
    assert sizes.max() >= 6, "the dual mesh should have polygon boundary faces"
    _check_against_openfoam(case, list(WARPED_PATCHES))
    # The formula matters: a plain vertex average misses by far more than the tolerance.
    g = geoms[0]
    naive = np.array(
        [g.points[g.labels[a:b]].mean(axis=0) for a, b in zip(g.offsets, g.offsets[1:])]
    )
    assert np.abs(naive - g.centres).max() > 1e-4


@pytest.mark.openfoam
def test_areas_sum_to_openfoams_patch_areas(tmp_path, run):
    """surfaceFieldValue reports each patch's total |Sf| and the flux of unit fields.

    Cost: under a second (blockMesh and postProcess).
    """
    case = _warped_case(tmp_path, "areas")
    run(case, "blockMesh")
    run(case, "polyDualMesh", "-overwrite", "60")
    funcs = "\n".join(
        f'  a_{p} {{ type surfaceFieldValue; libs ("libfieldFunctionObjects.so"); '
        f"regionType patch; name {p}; operation areaNormalIntegrate; fields (ex ey ez); "
        "writeFields false; writeArea true; log true; }"
        for p in WARPED_PATCHES
    )
    ctl = case / "system" / "controlDict"
    ctl.write_text(re.sub(r"functions\n\{\n", "functions\n{\n" + funcs + "\n", ctl.read_text()))
    for name, vec in (("ex", "1 0 0"), ("ey", "0 1 0"), ("ez", "0 0 1")):
        (case / "0" / name).write_text(
            testing.HEADER.format(cls="volVectorField", obj=name)
            + f"dimensions [0 0 0 0 0 0 0];\ninternalField uniform ({vec});\n"
            + f'boundaryField {{ ".*" {{ type calculated; value uniform ({vec}); }} }}\n'
        )
    run(case, "postProcess", "-time", "0", "-fields", "(ex ey ez)", log="log.areas")
    log = (case / "log.areas").read_text()
    mesh.clear_cache()
    for g in mesh.patch_geometry(case / "constant" / "polyMesh", list(WARPED_PATCHES)):
        block = log[log.index(f"surfaceFieldValue a_{g.name} write") :]
        area = float(re.search(r"total area\s*=\s*(\S+)", block).group(1))
        flux = [
            float(re.search(rf"areaNormalIntegrate\({g.name}\) of {e} = (\S+)", block).group(1))
            for e in ("ex", "ey", "ez")
        ]
        np.testing.assert_allclose(g.areas.sum(), area, rtol=1e-12)
        np.testing.assert_allclose(g.area_vectors.sum(axis=0), flux, rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(np.linalg.norm(g.normals, axis=1), 1.0, rtol=1e-12)


@pytest.mark.openfoam
def test_decomposed_case_is_read_rank_by_rank(tmp_path, run, cylinder_case):
    """Cost: under a second (blockMesh and decomposePar of the small cylinder)."""
    case = cylinder_case("par", decompose=2, split=(1, 2, 1))  # cuts the cylinder in two
    run(case, "blockMesh")
    run(case, "decomposePar", "-force")
    run(case, "postProcess", "-func", "writeCellCentres", "-time", "0", np=2, log="log.ppar")
    expected = []
    per_rank = []
    for proc in mesh.processor_dirs(case):
        ref = _reference(proc)
        per_rank.append(sum(len(e) for e in expected))
        for patch in ("cylinder", "jet2", "jet1"):
            value = ref.boundary_field[patch].get("value")
            if isinstance(value, np.ndarray) and value.size:  # "nonuniform 0()" is empty
                expected.append(value.reshape(-1, 3))
    expected = np.concatenate(expected)
    shutil.rmtree(case / "constant" / "polyMesh")  # only processor meshes remain
    mesh.clear_cache()
    g = mesh.interface_geometry(case, "Fluid-Mesh-body")  # parallel detected
    np.testing.assert_allclose(g.coordinates, expected, rtol=0, atol=1e-10)
    assert len(mesh.processor_dirs(case)) == 2
    assert 0 < per_rank[1] < len(expected), "both ranks must own part of the interface"
    # Rank 0 holds the bottom half (with jet2), rank 1 the top half (with jet1).
    n0 = per_rank[1]
    assert g.coordinates[:n0, 1].max() < g.coordinates[n0:, 1].min()


def _rewrite_binary(path: Path, arch: str, lists: list[np.ndarray]) -> None:
    head = path.read_bytes()
    end = head.index(b"}") + 1
    header = re.sub(rb'arch\s+"[^"]*"', f'arch        "{arch}"'.encode(), head[:end])
    body = b""
    for arr in lists:
        count = len(arr)
        body += b"\n%d\n(" % count + np.ascontiguousarray(arr).tobytes() + b")\n"
    path.write_bytes(header + b"\n" + body + b"\n// end\n")


@pytest.mark.openfoam
def test_binary_arch_label64_and_scalar32(tmp_path, run):
    """foamlib assumes label=32/scalar=64; other archs are read with the header's sizes.

    Cost: under a second (blockMesh and foamFormatConvert).
    """
    case = _warped_case(tmp_path, "arch", fmt="binary")
    run(case, "blockMesh")
    mesh_dir = case / "constant" / "polyMesh"
    mesh.clear_cache()
    before = mesh.patch_geometry(mesh_dir, ["xmax", "zmin"])
    offsets, labels = (np.asarray(a) for a in FoamFile(mesh_dir / "faces")[None])
    points = np.asarray(FoamFile(mesh_dir / "points")[None])
    _rewrite_binary(
        mesh_dir / "faces",
        "LSB;label=64;scalar=32",
        [offsets.astype("<i8"), labels.astype("<i8")],
    )
    _rewrite_binary(mesh_dir / "points", "LSB;label=64;scalar=32", [points.astype("<f4")])
    mesh.clear_cache()
    after = mesh.patch_geometry(mesh_dir, ["xmax", "zmin"])
    for a, b in zip(before, after):
        np.testing.assert_array_equal(a.labels, b.labels)
        np.testing.assert_allclose(a.centres, b.centres, rtol=1e-6, atol=1e-6)
    # A truncated binary list is reported, not misread.
    raw = (mesh_dir / "points").read_bytes()
    (mesh_dir / "points").write_bytes(raw[: len(raw) // 2])
    mesh.clear_cache()
    with pytest.raises(CaseError, match="points"):
        mesh.patch_geometry(mesh_dir, ["xmax"])


def test_face_centre_formula_on_known_shapes():
    # A unit square split oddly, a triangle and a non-convex pentagon in the z=0 plane.
    points = np.array(
        [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 0, 0], [3, 0, 0], [2, 1, 0],
         [0, 0, 1], [4, 0, 1], [4, 2, 1], [2, 1, 1], [0, 2, 1]],
        dtype=float,
    )  # fmt: skip
    offsets = np.array([0, 4, 7, 12])
    labels = np.array([0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11])
    centres, areas = mesh.face_centres_and_areas(points, offsets, labels)
    np.testing.assert_allclose(centres[0], [0.5, 0.5, 0.0])
    np.testing.assert_allclose(areas[0], [0, 0, 1.0])
    np.testing.assert_allclose(centres[1], [7 / 3, 1 / 3, 0])
    np.testing.assert_allclose(areas[1], [0, 0, 0.5])
    # Pentagon (0,0) (4,0) (4,2) (2,1) (0,2): area 8 - 2 = 6 (shoelace).
    np.testing.assert_allclose(areas[2], [0, 0, 6.0])
    assert centres[2][2] == pytest.approx(1.0)
    # Degenerate face: vertex average, zero area (as OpenFOAM marks tiny faces).
    c, a = mesh.face_centres_and_areas(np.zeros((4, 3)), np.array([0, 4]), np.arange(4))
    np.testing.assert_array_equal(a, 0.0)
    np.testing.assert_array_equal(c, 0.0)


def test_ascii_faces_with_any_layout(tmp_path):
    """One face per line (the OpenFOAM layout) and a free layout give the same faces."""
    body_lines = "4(0 1 2 3)\n5(1 2 3 4 5)\n3(5 6 7)\n6(1 2 3 4 5 6)\n"
    head = testing.HEADER.format(cls="faceList", obj="faces")
    mesh_dir = tmp_path / "polyMesh"
    mesh_dir.mkdir()
    (mesh_dir / "faces").write_text(head + f"\n4\n(\n{body_lines})\n\n// end\n")
    lined = mesh.read_faces(mesh_dir, 1, 4)
    (mesh_dir / "faces").write_text(
        head + "4 ( 4(0 1 2 3) 5(1 2 3 4 5)\n3(5 6 7) 6(1 2 3 4 5 6) )\n"
    )
    free = mesh.read_faces(mesh_dir, 1, 4)
    for a, b in zip(lined, free):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(lined[0], [0, 5, 8, 14])
    np.testing.assert_array_equal(lined[1], [1, 2, 3, 4, 5, 5, 6, 7, 1, 2, 3, 4, 5, 6])
    (mesh_dir / "faces").write_text(head + "2 ( 4(0 1 2) 3(1 2 3) )\n")
    with pytest.raises(CaseError, match="faces"):
        mesh.read_faces(mesh_dir, 0, 2)


def test_precice_dict_interfaces(tmp_path):
    system = tmp_path / "system"
    system.mkdir()
    (system / "preciceDict").write_text(
        testing.HEADER.format(cls="dictionary", obj="preciceDict")
        + """preciceConfig "../precice-config.xml";
participant Fluid;
modules (FF);
interfaces
{
  Interface1
  {
    mesh              Fluid-Mesh-jets;
    patches
    (
        jet1
        jet2
    );
    locations         faceCentres;
    readData          (Velocity);
    writeData         ();
  };
  Interface2 { mesh Fluid-Mesh-nodes; patches (cylinder); locations faceNodes;
               readData (); writeData (Pressure Velocity); connectivity true; };
};
"""
    )
    pdict = mesh.read_precice_dict(tmp_path)
    assert pdict.participant == "Fluid"
    assert pdict.config == "../precice-config.xml"
    assert pdict.modules == ("FF",)
    jets = pdict.interface_for_mesh("Fluid-Mesh-jets")
    assert jets.patches == ("jet1", "jet2")
    assert jets.location_kind == "faceCenters"
    assert jets.read_data == ("Velocity",) and jets.write_data == ()
    nodes = pdict.interface_for_mesh("Fluid-Mesh-nodes")
    assert nodes.location_kind == "faceNodes" and nodes.connectivity
    assert nodes.write_data == ("Pressure", "Velocity")
    assert pdict.interface_for_mesh("nope") is None
    # Old list syntax.
    (system / "preciceDict").write_text(
        'preciceConfig "x.xml"; participant F; interfaces ( { mesh M; patches (a b); } );'
    )
    (only,) = mesh.read_precice_dict(tmp_path).interfaces
    assert only.mesh == "M" and only.patches == ("a", "b")


@pytest.mark.openfoam
def test_interface_geometry_order_dimensions_and_nodes(tmp_path, run, cylinder_case):
    """Cost: under a second (one blockMesh of the small cylinder)."""
    case = cylinder_case("geo")
    run(case, "blockMesh")
    run(case, "postProcess", "-func", "writeCellCentres", "-time", "0")
    ref = _reference(case)
    mesh.clear_cache()
    body = mesh.interface_geometry(case, "Fluid-Mesh-body", dimensions=2)
    expected = np.concatenate(
        [np.asarray(ref.boundary_field[p]["value"]) for p in ("cylinder", "jet2", "jet1")]
    )
    assert body.coordinates.shape == (len(expected), 2)  # z dropped for a 2-D mesh
    np.testing.assert_allclose(body.coordinates, expected[:, :2], atol=1e-10)
    assert body.patches == ("cylinder", "jet2", "jet1")
    assert body.normals.shape == (len(expected), 3) and body.areas.shape == (len(expected),)
    jet1 = mesh.interface_geometry(case, "Fluid-Mesh-jet1")
    np.testing.assert_allclose(jet1.coordinates, np.asarray(ref.boundary_field["jet1"]["value"]))
    # Jet 1 sits on top of the cylinder: its outward normals point into it (down).
    assert np.all(jet1.normals[:, 1] < -0.99)
    nodes = mesh.interface_geometry(case, "Fluid-Mesh-nodes", dimensions=3)
    assert nodes.normals is None and nodes.areas is None
    geoms = mesh.patch_geometry(case / "constant" / "polyMesh", ["jet1", "jet2"])
    for g in geoms:
        # localPoints: each point once, in order of first appearance in the faces.
        seen: list[int] = []
        for label in g.labels.tolist():
            if label not in seen:
                seen.append(label)
        np.testing.assert_array_equal(g.local_points(), g.points[seen])
    assert len(nodes.coordinates) == sum(len(g.local_points()) for g in geoms)


@pytest.mark.openfoam
def test_missing_patch_names_precice_dict_and_available_patches(tmp_path, run, cylinder_case):
    """Cost: under a second (one blockMesh of the small cylinder)."""
    case = cylinder_case("bad")
    (case / "system" / "preciceDict").write_text(
        testing.precice_dict({"I": {"mesh": "Fluid-Mesh", "patches": ["jet1", "jet3"]}})
    )
    run(case, "blockMesh")
    mesh.clear_cache()
    with pytest.raises(CaseError) as err:
        mesh.interface_geometry(case, "Fluid-Mesh")
    text = str(err.value)
    assert "preciceDict" in text and "'jet3'" in text
    assert "jet1" in text and "cylinder" in text and "inlet" in text
    with pytest.raises(CaseError, match="no interface uses mesh 'Other'"):
        mesh.interface_geometry(case, "Other")


def test_missing_mesh_and_dict_are_clear_errors(tmp_path):
    (tmp_path / "system").mkdir()
    with pytest.raises(CaseError, match="preciceDict"):
        mesh.read_precice_dict(tmp_path)
    with pytest.raises(CaseError, match="no mesh"):
        mesh.patch_geometry(tmp_path / "constant" / "polyMesh", ["a"])
