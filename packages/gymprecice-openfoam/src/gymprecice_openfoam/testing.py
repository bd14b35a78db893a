"""Small OpenFOAM cases written from Python, for tests and benchmarks.

The flagship geometry is the flow-control benchmark: a cylinder in a channel with two
synthetic-jet slots at 90 and 270 degrees. :func:`cylinder_block_mesh_dict` builds it
for blockMesh as an O-grid of eight sectors around the cylinder (the two 10-degree jet
sectors become patches ``jet1``/``jet2``) inside a block-structured channel, at any
resolution: ``resolution=1`` gives about 1,200 cells, ``resolution=3.7`` about 16,500.
:func:`write_flow_case` adds what ``pimpleFoam`` needs, with optional probes, forces,
force coefficients and the preCICE adapter's function object.
"""

from __future__ import annotations

import math
import os
import shutil
from collections.abc import Mapping, Sequence
from pathlib import Path

HEADER = "FoamFile {{ version 2.0; format ascii; class {cls}; object {obj}; }}\n"

#: Patches of the cylinder case and their kind.
CYLINDER_PATCHES = {
    "inlet": "inlet",
    "outlet": "outlet",
    "walls": "wall",
    "cylinder": "wall",
    "jet1": "wall",
    "jet2": "wall",
    "frontAndBack": "empty",
}


def _fmt(v: float) -> str:
    return f"{v:.12g}"


def missing_coupled_stack(*programs: str) -> list[str]:
    """What a real OpenFOAM-preCICE run lacks on this machine (empty when all is there).

    Checks pyprecice v3, each OpenFOAM program in ``programs`` on the PATH and, when they
    are all there, the OpenFOAM-preCICE adapter's library. The real-stack tests skip
    with this list as the reason (``GYMPRECICE_REQUIRE_REAL=1`` turns the skip into a
    failure).
    """
    missing = []
    try:
        import precice

        if not hasattr(precice, "Participant"):
            missing.append("pyprecice v3")
    except ImportError:
        missing.append("pyprecice (the preCICE library and its Python bindings)")
    absent = [program for program in programs if shutil.which(program) is None]
    missing += [f"OpenFOAM ({program})" for program in absent]
    if not absent:
        from gymprecice.plugin import CaseError
        from gymprecice_openfoam.installation import find_openfoam

        try:
            adapter = find_openfoam().find_library()
        except CaseError:
            adapter = None
        if adapter is None:
            missing.append("the OpenFOAM-preCICE adapter (libpreciceAdapterFunctionObject.so)")
    return missing


def cylinder_block_mesh_dict(
    resolution: float = 1.0,
    *,
    length: float = 2.2,
    height: float = 0.41,
    centre: tuple[float, float] = (0.2, 0.2),
    radius: float = 0.05,
    box: float = 0.1,
    depth: float = 0.01,
    jet_width_deg: float = 10.0,
) -> str:
    """blockMeshDict of a 2-D channel with a cylinder and two jets (one cell deep)."""
    cx, cy = centre
    half = jet_width_deg / 2
    breaks = [45, 90 - half, 90 + half, 135, 225, 270 - half, 270 + half, 315]
    n_ang = {40: max(2, round(4 * resolution)), 90: max(2, round(10 * resolution))}
    n_jet = max(2, round(2 * resolution))
    n_rad = max(2, round(8 * resolution))
    n_left, n_right = max(2, round(4 * resolution)), max(4, round(40 * resolution))
    n_bottom, n_top = max(2, round(4 * resolution)), max(2, round(4 * resolution))

    vertices: list[tuple[float, float, float]] = []
    index: dict[tuple[float, float, float], int] = {}

    def vid(x: float, y: float, z: float) -> int:
        key = (round(x, 12), round(y, 12), round(z, 12))
        if key not in index:
            index[key] = len(vertices)
            vertices.append(key)
        return index[key]

    def square(a_deg: float) -> tuple[float, float]:
        a = math.radians(a_deg)
        c, s = math.cos(a), math.sin(a)
        k = box / max(abs(c), abs(s))
        return cx + k * c, cy + k * s

    def circle(a_deg: float) -> tuple[float, float]:
        a = math.radians(a_deg)
        return cx + radius * math.cos(a), cy + radius * math.sin(a)

    blocks, edges = [], []
    faces: dict[str, list[str]] = {name: [] for name in CYLINDER_PATCHES}
    sectors = list(zip(breaks, [*breaks[1:], breaks[0] + 360]))
    for a0, a1 in sectors:
        span = a1 - a0
        n_a = n_jet if span < 20 else n_ang[40] if span < 60 else n_ang[90]
        i0, o0, o1, i1 = circle(a0), square(a0), square(a1), circle(a1)
        v = [vid(*p, 0.0) for p in (i0, o0, o1, i1)] + [vid(*p, depth) for p in (i0, o0, o1, i1)]
        blocks.append(f"hex ({' '.join(map(str, v))}) ({n_rad} {n_a} 1) simpleGrading (1 1 1)")
        mid = circle((a0 + a1) / 2)
        for z, (va, vb) in ((0.0, (v[0], v[3])), (depth, (v[4], v[7]))):
            edges.append(f"arc {va} {vb} ({_fmt(mid[0])} {_fmt(mid[1])} {_fmt(z)})")
        inner = f"({v[0]} {v[4]} {v[7]} {v[3]})"
        if abs((a0 + a1) / 2 - 90) < 1e-9:
            faces["jet1"].append(inner)
        elif abs((a0 + a1) / 2 - 270) < 1e-9:
            faces["jet2"].append(inner)
        else:
            faces["cylinder"].append(inner)
        faces["frontAndBack"] += [
            f"({v[0]} {v[3]} {v[2]} {v[1]})",
            f"({v[4]} {v[5]} {v[6]} {v[7]})",
        ]

    xj_left, xj_right = square(90 + half)[0], square(90 - half)[0]
    xs = [0.0, cx - box, xj_left, xj_right, cx + box, length]
    ys = [0.0, cy - box, cy + box, height]
    nx = [n_left, n_ang[40], n_jet, n_ang[40], n_right]
    ny = [n_bottom, n_ang[90], n_top]
    for j in range(5):
        for i in range(3):
            if i == 1 and 1 <= j <= 3:
                continue  # the O-grid fills the square around the cylinder
            corners = [
                (xs[j], ys[i]),
                (xs[j + 1], ys[i]),
                (xs[j + 1], ys[i + 1]),
                (xs[j], ys[i + 1]),
            ]
            v = [vid(*p, 0.0) for p in corners] + [vid(*p, depth) for p in corners]
            blocks.append(
                f"hex ({' '.join(map(str, v))}) ({nx[j]} {ny[i]} 1) simpleGrading (1 1 1)"
            )
            if j == 0:
                faces["inlet"].append(f"({v[0]} {v[4]} {v[7]} {v[3]})")
            if j == 4:
                faces["outlet"].append(f"({v[1]} {v[2]} {v[6]} {v[5]})")
            if i == 0:
                faces["walls"].append(f"({v[0]} {v[1]} {v[5]} {v[4]})")
            if i == 2:
                faces["walls"].append(f"({v[3]} {v[7]} {v[6]} {v[2]})")
            faces["frontAndBack"] += [
                f"({v[0]} {v[3]} {v[2]} {v[1]})",
                f"({v[4]} {v[5]} {v[6]} {v[7]})",
            ]

    lines = [HEADER.format(cls="dictionary", obj="blockMeshDict"), "scale 1;", "vertices", "("]
    lines += [f"    ({_fmt(x)} {_fmt(y)} {_fmt(z)})" for x, y, z in vertices]
    lines += [");", "blocks", "("] + [f"    {b}" for b in blocks] + [");"]
    lines += ["edges", "("] + [f"    {e}" for e in edges] + [");", "boundary", "("]
    for name, kind in CYLINDER_PATCHES.items():
        ftype = {"inlet": "patch", "outlet": "patch"}.get(kind, kind)
        lines.append(f"    {name} {{ type {ftype}; faces ( {' '.join(faces[name])} ); }}")
    lines += [");", "mergePatchPairs ();", ""]
    return "\n".join(lines)


def cylinder_cells(resolution: float) -> int:
    """Number of cells :func:`cylinder_block_mesh_dict` makes at ``resolution``."""
    n40, n90 = max(2, round(4 * resolution)), max(2, round(10 * resolution))
    n_jet, n_rad = max(2, round(2 * resolution)), max(2, round(8 * resolution))
    n_left, n_right = max(2, round(4 * resolution)), max(4, round(40 * resolution))
    n_bt = max(2, round(4 * resolution))
    ogrid = n_rad * (4 * n40 + 2 * n_jet + 2 * n90)
    columns = n_left + 2 * n40 + n_jet + n_right
    return ogrid + columns * 2 * n_bt + (n_left + n_right) * n90


def control_dict(
    *,
    application: str = "pimpleFoam",
    end_time: float = 0.05,
    delta_t: float = 0.005,
    write_interval: float | None = None,
    write_format: str = "ascii",
    write_precision: int = 8,
    compression: bool = False,
    probes: Sequence[Sequence[float]] = (),
    probe_fields: Sequence[str] = ("p", "U"),
    force_patches: Sequence[str] = (),
    adapter: bool = True,
    start_from: str = "startTime",
) -> str:
    """A controlDict with the function objects the tests and benchmarks read."""
    interval = end_time if write_interval is None else write_interval
    functions = []
    if adapter:
        functions.append(
            "    preCICE_Adapter { type preciceAdapterFunctionObject; "
            'libs ("libpreciceAdapterFunctionObject.so"); }'
        )
    if probes:
        locations = " ".join(f"({' '.join(_fmt(c) for c in p)})" for p in probes)
        functions.append(
            f'    probes {{ type probes; libs ("libsampling.so"); writeControl timeStep; '
            f"writeInterval 1; fields ({' '.join(probe_fields)}); probeLocations ({locations}); }}"
        )
    if force_patches:
        patches = " ".join(force_patches)
        common = f"patches ({patches}); rho rhoInf; rhoInf 1; CofR (0.2 0.2 0);"
        functions.append(
            f'    forces {{ type forces; libs ("libforces.so"); writeControl timeStep; '
            f"writeInterval 1; {common} }}"
        )
        functions.append(
            f'    forceCoeffs {{ type forceCoeffs; libs ("libforces.so"); writeControl timeStep; '
            f"writeInterval 1; {common} liftDir (0 1 0); dragDir (1 0 0); pitchAxis (0 0 1); "
            "magUInf 1; lRef 0.1; Aref 0.001; }"
        )
    body = "\n".join(functions)
    return (
        HEADER.format(cls="dictionary", obj="controlDict")
        + f"application {application};\nstartFrom {start_from};\nstartTime 0;\n"
        + f"stopAt endTime;\nendTime {_fmt(end_time)};\ndeltaT {_fmt(delta_t)};\n"
        + f"writeControl runTime;\nwriteInterval {_fmt(interval)};\npurgeWrite 0;\n"
        + f"writeFormat {write_format};\nwritePrecision {write_precision};\n"
        + f"writeCompression {'on' if compression else 'off'};\ntimeFormat general;\n"
        + f"timePrecision 6;\nrunTimeModifiable false;\nfunctions\n{{\n{body}\n}}\n"
    )


FV_SCHEMES = HEADER.format(cls="dictionary", obj="fvSchemes") + (
    "ddtSchemes { default Euler; }\ngradSchemes { default Gauss linear; }\n"
    "divSchemes { default none; div(phi,U) Gauss linear; "
    "div((nuEff*dev2(T(grad(U))))) Gauss linear; }\n"
    "laplacianSchemes { default Gauss linear corrected; }\n"
    "interpolationSchemes { default linear; }\nsnGradSchemes { default corrected; }\n"
)

FV_SOLUTION = HEADER.format(cls="dictionary", obj="fvSolution") + (
    'solvers { "(p|pFinal)" { solver PCG; preconditioner DIC; tolerance 1e-06; relTol 0; }\n'
    '  "(U|UFinal)" { solver smoothSolver; smoother symGaussSeidel; tolerance 1e-05; '
    "relTol 0; } }\n"
    "PIMPLE { nOuterCorrectors 1; nCorrectors 2; nNonOrthogonalCorrectors 0; "
    "pRefCell 0; pRefValue 0; }\n"
    "PISO { nCorrectors 2; nNonOrthogonalCorrectors 0; pRefCell 0; pRefValue 0; }\n"
)


def _fields(patches: Mapping[str, str], inflow: tuple[float, float, float]) -> tuple[str, str]:
    u_bc, p_bc = [], []
    for name, kind in patches.items():
        if kind == "inlet":
            u_bc.append(
                f"    {name} {{ type fixedValue; value uniform ({' '.join(map(_fmt, inflow))}); }}"
            )
            p_bc.append(f"    {name} {{ type zeroGradient; }}")
        elif kind == "outlet":
            u_bc.append(f"    {name} {{ type zeroGradient; }}")
            p_bc.append(f"    {name} {{ type fixedValue; value uniform 0; }}")
        elif kind == "empty":
            u_bc.append(f"    {name} {{ type empty; }}")
            p_bc.append(f"    {name} {{ type empty; }}")
        elif kind == "moving":
            u_bc.append(f"    {name} {{ type fixedValue; value uniform (1 0 0); }}")
            p_bc.append(f"    {name} {{ type zeroGradient; }}")
        else:
            u_bc.append(f"    {name} {{ type noSlip; }}")
            p_bc.append(f"    {name} {{ type zeroGradient; }}")
    u = (
        HEADER.format(cls="volVectorField", obj="U")
        + "dimensions [0 1 -1 0 0 0 0];\ninternalField uniform (0 0 0);\n"
        + "boundaryField\n{\n"
        + "\n".join(u_bc)
        + "\n}\n"
    )
    p = (
        HEADER.format(cls="volScalarField", obj="p")
        + "dimensions [0 2 -2 0 0 0 0];\ninternalField uniform 0;\n"
        + "boundaryField\n{\n"
        + "\n".join(p_bc)
        + "\n}\n"
    )
    return u, p


def write_flow_case(
    case_dir: str | os.PathLike[str],
    block_mesh_dict: str,
    patches: Mapping[str, str],
    *,
    inflow: tuple[float, float, float] = (1.0, 0.0, 0.0),
    nu: float = 0.001,
    precice_dict: str | None = None,
    decompose: int = 1,
    split: tuple[int, int, int] | None = None,
    **control: object,
) -> Path:
    """Write a pimpleFoam case (mesh recipe, fields, dictionaries) into ``case_dir``."""
    case = Path(case_dir)
    for sub in ("system", "constant", "0"):
        (case / sub).mkdir(parents=True, exist_ok=True)
    (case / "system" / "blockMeshDict").write_text(block_mesh_dict)
    (case / "system" / "controlDict").write_text(control_dict(**control))  # type: ignore[arg-type]
    (case / "system" / "fvSchemes").write_text(FV_SCHEMES)
    (case / "system" / "fvSolution").write_text(FV_SOLUTION)
    (case / "constant" / "transportProperties").write_text(
        HEADER.format(cls="dictionary", obj="transportProperties")
        + f"transportModel Newtonian;\nnu {_fmt(nu)};\n"
    )
    (case / "constant" / "turbulenceProperties").write_text(
        HEADER.format(cls="dictionary", obj="turbulenceProperties") + "simulationType laminar;\n"
    )
    u, p = _fields(patches, inflow)
    (case / "0" / "U").write_text(u)
    (case / "0" / "p").write_text(p)
    if precice_dict is not None:
        (case / "system" / "preciceDict").write_text(precice_dict)
    if decompose > 1:
        (case / "system" / "decomposeParDict").write_text(
            HEADER.format(cls="dictionary", obj="decomposeParDict")
            + f"numberOfSubdomains {decompose};\nmethod simple;\n"
            + f"simpleCoeffs {{ n ({' '.join(map(str, split or (decompose, 1, 1)))}); "
            + "delta 0.001; }\n"
        )
    return case


def precice_dict(interfaces: Mapping[str, Mapping[str, object]], participant: str = "Fluid") -> str:
    """A system/preciceDict; each interface maps to {mesh, patches, locations, ...}."""
    blocks = []
    for name, spec in interfaces.items():
        patches = "\n        ".join(str(p) for p in spec["patches"])  # type: ignore[union-attr]
        blocks.append(
            f"    {name}\n    {{\n        mesh {spec['mesh']};\n"
            f"        patches\n        (\n        {patches}\n        );\n"
            f"        locations {spec.get('locations', 'faceCenters')};\n"
            f"        readData ({' '.join(spec.get('read', ()))});\n"  # type: ignore[arg-type]
            f"        writeData ({' '.join(spec.get('write', ()))});\n    }};"  # type: ignore[arg-type]
        )
    return (
        HEADER.format(cls="dictionary", obj="preciceDict")
        + f'preciceConfig "../precice-config.xml";\nparticipant {participant};\nmodules (FF);\n'
        + "interfaces\n{\n"
        + "\n".join(blocks)
        + "\n};\n"
    )
