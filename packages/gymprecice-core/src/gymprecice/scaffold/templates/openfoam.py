"""Kind ``openfoam``: the case of a 2-D channel (pimpleFoam, laminar) whose inlet
velocity the controller sets, coupled by the OpenFOAM-preCICE adapter.
"""

from __future__ import annotations

__all__ = ["OPENFOAM_FILES"]

_FOAM = "FoamFile {{ version 2.0; format ascii; class {cls}; object {obj}; }}\n"

OPENFOAM_FILES = {
    "system/blockMeshDict": _FOAM.format(cls="dictionary", obj="blockMeshDict")
    + """\
// a 2-D channel 1 x 0.2 m, one cell thick in z
scale 1;
vertices
(
    (0 0 0) (1 0 0) (1 0.2 0) (0 0.2 0)
    (0 0 0.01) (1 0 0.01) (1 0.2 0.01) (0 0.2 0.01)
);
blocks ( hex (0 1 2 3 4 5 6 7) (50 10 1) simpleGrading (1 1 1) );
boundary
(
    inlet { type patch; faces ((0 4 7 3)); }
    outlet { type patch; faces ((1 2 6 5)); }
    walls { type wall; faces ((0 1 5 4) (3 7 6 2)); }
    frontAndBack { type empty; faces ((0 3 2 1) (4 5 6 7)); }
);
""",
    "system/controlDict": _FOAM.format(cls="dictionary", obj="controlDict")
    + """\
application pimpleFoam;
startFrom startTime;
startTime 0;
stopAt endTime;
// the coupling (preCICE max-time) ends the run; keep this at least as long
endTime 10;
// must equal the preCICE time-window size
deltaT {{window}};
writeControl runTime;
writeInterval 10;
purgeWrite 0;
writeFormat ascii;
writePrecision 8;
writeCompression off;
timeFormat general;
timePrecision 6;
runTimeModifiable false;
functions
{
    preCICE_Adapter { type preciceAdapterFunctionObject; libs ("libpreciceAdapterFunctionObject.so"); }
}
""",
    "system/fvSchemes": _FOAM.format(cls="dictionary", obj="fvSchemes")
    + """\
ddtSchemes { default Euler; }
gradSchemes { default Gauss linear; }
divSchemes { default none; div(phi,U) Gauss linear; div((nuEff*dev2(T(grad(U))))) Gauss linear; }
laplacianSchemes { default Gauss linear corrected; }
interpolationSchemes { default linear; }
snGradSchemes { default corrected; }
""",
    "system/fvSolution": _FOAM.format(cls="dictionary", obj="fvSolution")
    + """\
solvers { "(p|pFinal)" { solver PCG; preconditioner DIC; tolerance 1e-06; relTol 0; }
  "(U|UFinal)" { solver smoothSolver; smoother symGaussSeidel; tolerance 1e-05; relTol 0; } }
PIMPLE { nOuterCorrectors 1; nCorrectors 2; nNonOrthogonalCorrectors 0; pRefCell 0; pRefValue 0; }
PISO { nCorrectors 2; nNonOrthogonalCorrectors 0; pRefCell 0; pRefValue 0; }
""",
    "system/preciceDict": _FOAM.format(cls="dictionary", obj="preciceDict")
    + """\
preciceConfig "../precice-config.xml";
participant {{participant}};
modules (FF);
interfaces
{
    Inlet
    {
        mesh {{mesh}};
        patches (inlet);
        locations faceCenters;
        readData ({{write}});
        writeData ({{read}});
    };
};
""",
    "constant/transportProperties": _FOAM.format(cls="dictionary", obj="transportProperties")
    + """\
transportModel Newtonian;
nu 0.001;
""",
    "constant/turbulenceProperties": _FOAM.format(cls="dictionary", obj="turbulenceProperties")
    + """\
simulationType laminar;
""",
    "0/U": _FOAM.format(cls="volVectorField", obj="U")
    + """\
dimensions [0 1 -1 0 0 0 0];
internalField uniform (0 0 0);
boundaryField
{
    // the adapter overwrites the value of a fixedValue patch: the inlet must be fixedValue
    inlet { type fixedValue; value uniform (0.1 0 0); }
    outlet { type zeroGradient; }
    walls { type noSlip; }
    frontAndBack { type empty; }
}
""",
    "0/p": _FOAM.format(cls="volScalarField", obj="p")
    + """\
dimensions [0 2 -2 0 0 0 0];
internalField uniform 0;
boundaryField
{
    inlet { type zeroGradient; }
    outlet { type fixedValue; value uniform 0; }
    walls { type zeroGradient; }
    frontAndBack { type empty; }
}
""",
}
