"""The flow's OpenFOAM dictionaries: fields, properties, controlDict, schemes, outputs.

Everything of the OpenFOAM case but the mesh (:mod:`~gymprecice_tutorials.recipes.mesh`)
and the preCICE adapter's files (:mod:`~gymprecice_tutorials.recipes.coupling`).
"""

from __future__ import annotations

from gymprecice_tutorials.recipes.foam_format import (
    BANNER,
    FOOTER,
    boundary_field,
    foam_header,
    foam_number,
    foam_vector,
)
from gymprecice_tutorials.recipes.probes import probe_locations
from gymprecice_tutorials.recipes.spec import CaseSpec


def _u_file(spec: CaseSpec) -> str:
    g, f = spec.geometry, spec.flow
    # parabolic inflow u(y) = 4 Umax y (H - y) / H^2, as a polynomial in y (fixedProfile)
    a1 = 4 * f.u_max / g.height
    a2 = -4 * f.u_max / g.height**2
    bcs = {
        "inlet": (
            "type            fixedProfile;\n"
            # Polynomial<vector>: (coefficient exponent) pairs, both of the field's type
            f"profile         polynomial ((({foam_number(a1)} 0 0) (1 1 1)) "
            f"(({foam_number(a2)} 0 0) (2 2 2)));\n"
            "direction       (0 1 0);\n"
            "origin          0;"
        ),
        "outlet": "type            inletOutlet;\ninletValue      uniform (0 0 0);\n"
        "value           uniform (0 0 0);",
        "walls": "type            noSlip;",
    }
    if spec.control == "rotation":
        bcs["cylinder"] = (
            "// wall velocity set by the preCICE adapter (rotation omega x r)\n"
            "type            fixedValue;\nvalue           uniform (0 0 0);"
        )
    else:
        bcs["cylinder"] = "type            noSlip;"
    if spec.control == "jets":
        for jet in ("jet1", "jet2"):
            bcs[jet] = (
                "// jet velocity set by the preCICE adapter\n"
                "type            fixedValue;\nvalue           uniform (0 0 0);"
            )
    bcs["frontAndBack"] = "type            empty;"
    return (
        foam_header("volVectorField", "0", "U")
        + "dimensions      [0 1 -1 0 0 0 0];\n\ninternalField   uniform (0 0 0);\n\n"
        + boundary_field(bcs)
        + FOOTER
    )


def _p_file(spec: CaseSpec) -> str:
    bcs = {
        "inlet": "type            zeroGradient;",
        "outlet": "type            fixedValue;\nvalue           uniform 0;",
        "walls": "type            zeroGradient;",
        "cylinder": "type            zeroGradient;",
    }
    if spec.control == "jets":
        bcs["jet1"] = "type            zeroGradient;"
        bcs["jet2"] = "type            zeroGradient;"
    bcs["frontAndBack"] = "type            empty;"
    return (
        foam_header("volScalarField", "0", "p")
        + "dimensions      [0 2 -2 0 0 0 0];\n\ninternalField   uniform 0;\n\n"
        + boundary_field(bcs)
        + FOOTER
    )


def _transport(spec: CaseSpec) -> str:
    return (
        foam_header("dictionary", "constant", "transportProperties")
        + "transportModel  Newtonian;\n\n"
        + f"nu              [0 2 -1 0 0 0 0] {foam_number(spec.flow.nu)};\n"
        + FOOTER
    )


def _laminar(obj: str) -> str:
    return foam_header("dictionary", "constant", obj) + "simulationType  laminar;\n" + FOOTER


def _end_time(spec: CaseSpec) -> float:
    if spec.end_time is not None:
        return spec.end_time
    return round(spec.prerun_end_time + spec.episode_time, 10)


def _control_dict(spec: CaseSpec) -> str:
    end = _end_time(spec)
    interval = spec.write_interval or end
    return (
        foam_header("dictionary", "system", "controlDict")
        + "application     pimpleFoam;\n\n"
        + "startFrom       latestTime;\nstartTime       0;\n\n"
        + f"stopAt          endTime;\nendTime         {foam_number(end)};\n\n"
        + f"deltaT          {foam_number(spec.flow.dt)};\n\n"
        + f"writeControl    adjustableRunTime;\nwriteInterval   {foam_number(interval)};\n"
        + "purgeWrite      0;\n\n"
        + "writeFormat     ascii;\nwritePrecision  10;\nwriteCompression off;\n\n"
        + "timeFormat      general;\ntimePrecision   8;\n\n"
        + "runTimeModifiable false;\n\nadjustTimeStep  no;\n\n"
        + "functions\n{\n"
        + '    #include "probes"\n'
        + '    #include "forceCoeffs"\n'
        + "    // the preCICE adapter; an uncoupled run empties this file (recipes.make_uncoupled)\n"
        + '    #include "preciceAdapterFunctionObject"\n'
        + "}\n"
        + FOOTER
    )


def _probes(spec: CaseSpec) -> str:
    locs = "\n".join(f"        {foam_vector(*p)}" for p in probe_locations(spec.geometry))
    return (
        BANNER
        + "// Included by controlDict: 151 pressure probes (Rabault et al. 2019 layout)\n\n"
        + 'probes\n{\n    type            probes;\n    libs            ("libsampling.so");\n'
        + "    writeControl    timeStep;\n    writeInterval   1;\n"
        + "    fields          (p);\n"
        + f"    probeLocations\n    (\n{locs}\n    );\n}}\n"
    )


def _force_coeffs(spec: CaseSpec) -> str:
    g, f = spec.geometry, spec.flow
    patches = " ".join(("cylinder", *(("jet1", "jet2") if spec.control == "jets" else ())))
    cx, cy = g.centre
    return (
        BANNER
        + "// Included by controlDict: drag/lift coefficients on the cylinder wall, with\n"
        + "// Cd = 2 Fx / (rho Umean^2 D depth), Cl likewise (Schäfer-Turek definitions)\n\n"
        + 'forceCoeffs\n{\n    type            forceCoeffs;\n    libs            ("libforces.so");\n'
        + "    writeControl    timeStep;\n    writeInterval   1;\n"
        + f"    patches         ({patches});\n"
        + "    rho             rhoInf;\n    rhoInf          1;\n"
        + f"    CofR            {foam_vector(cx, cy, 0.0)};\n"
        + "    liftDir         (0 1 0);\n    dragDir         (1 0 0);\n"
        + "    pitchAxis       (0 0 1);\n"
        + f"    magUInf         {foam_number(f.u_mean)};\n"
        + f"    lRef            {foam_number(g.diameter)};\n"
        + f"    Aref            {foam_number(g.diameter * g.depth)};\n}}\n"
    )


def _fv_schemes() -> str:
    return (
        foam_header("dictionary", "system", "fvSchemes")
        + "ddtSchemes\n{\n    default         backward;\n}\n\n"
        + "gradSchemes\n{\n    default         Gauss linear;\n}\n\n"
        + "divSchemes\n{\n    default         none;\n"
        + "    div(phi,U)      Gauss linearUpwind grad(U);\n"
        + "    div((nuEff*dev2(T(grad(U))))) Gauss linear;\n}\n\n"
        + "laplacianSchemes\n{\n    default         Gauss linear corrected;\n}\n\n"
        + "interpolationSchemes\n{\n    default         linear;\n}\n\n"
        + "snGradSchemes\n{\n    default         corrected;\n}\n"
        + FOOTER
    )


def _fv_solution(spec: CaseSpec) -> str:
    return (
        foam_header("dictionary", "system", "fvSolution")
        + "solvers\n{\n"
        + "    p\n    {\n        solver          GAMG;\n        smoother        GaussSeidel;\n"
        + "        tolerance       1e-06;\n        relTol          0.01;\n    }\n\n"
        + "    pFinal\n    {\n        $p;\n        relTol          0;\n    }\n\n"
        + '    "(U|UFinal)"\n    {\n        solver          smoothSolver;\n'
        + "        smoother        symGaussSeidel;\n        tolerance       1e-08;\n"
        + "        relTol          0;\n    }\n}\n\n"
        + "PIMPLE\n{\n    momentumPredictor yes;\n"
        + f"    nOuterCorrectors {spec.flow.outer_correctors};\n"
        + "    nCorrectors     2;\n    nNonOrthogonalCorrectors 0;\n"
        + "    pRefCell        0;\n    pRefValue       0;\n}\n"
        + FOOTER
    )


def _decompose(spec: CaseSpec) -> str:
    n = max(1, spec.n_procs)
    return (
        foam_header("dictionary", "system", "decomposeParDict")
        + f"numberOfSubdomains {n};\n\nmethod          simple;\n\n"
        + f"coeffs\n{{\n    n               ({n} 1 1);\n}}\n"
        + FOOTER
    )


def flow_files(spec: CaseSpec) -> dict[str, str]:
    """The flow's dictionaries (relative to ``fluid-openfoam/``), the mesh's excepted."""
    return {
        "0/U": _u_file(spec),
        "0/p": _p_file(spec),
        "constant/transportProperties": _transport(spec),
        "constant/turbulenceProperties": _laminar("turbulenceProperties"),
        "constant/momentumTransport": _laminar("momentumTransport"),
        "system/controlDict": _control_dict(spec),
        "system/fvSchemes": _fv_schemes(),
        "system/fvSolution": _fv_solution(spec),
        "system/decomposeParDict": _decompose(spec),
        "system/probes": _probes(spec),
        "system/forceCoeffs": _force_coeffs(spec),
    }
