"""How a case couples: preCICE's configuration, gymprecice's, and the OpenFOAM adapter's.

The controller writes ``Velocity`` on one mesh per actuated patch; the fluid reads it
there through the OpenFOAM-preCICE adapter (``system/preciceDict``), which controlDict
includes from ``system/preciceAdapterFunctionObject``. An uncoupled run (pre-run,
validation) empties that file (:func:`gymprecice_tutorials.recipes.case.make_uncoupled`).
"""

from __future__ import annotations

from gymprecice_tutorials.recipes.foam_format import BANNER, FOOTER, foam_header, foam_number
from gymprecice_tutorials.recipes.spec import FLUID_DIR, PRECICE_FO_FILE, CaseSpec

PRECICE_FUNCTION_OBJECT = (
    "preCICE_Adapter\n{\n    type            preciceAdapterFunctionObject;\n"
    '    libs            ("libpreciceAdapterFunctionObject.so");\n}\n'
)
UNCOUPLED_FUNCTION_OBJECT = "// uncoupled run: the preCICE adapter function object is dropped\n"


def adapter_function_object() -> str:
    return (
        BANNER
        + "// Included by controlDict: the OpenFOAM-preCICE adapter (coupled runs)\n\n"
        + PRECICE_FUNCTION_OBJECT
    )


def mesh_name(participant: str, interface: str) -> str:
    return f"{participant}-Mesh-{interface}"


def precice_dict(spec: CaseSpec) -> str:
    blocks = []
    for k, name in enumerate(spec.interfaces, start=1):
        blocks.append(
            f"    Interface{k}\n    {{\n        mesh            {mesh_name('Fluid', name)};\n"
            f"        patches         ({name});\n        locations       faceCenters;\n"
            "        readData        (Velocity);\n        writeData       ();\n    }"
        )
    return (
        foam_header("dictionary", "system", "preciceDict")
        + 'preciceConfig   "../precice-config.xml";\n\nparticipant     Fluid;\n\n'
        + "modules         (FF);\n\n"
        + "interfaces\n{\n"
        + "\n".join(blocks)
        + "\n}\n\nFF\n{\n    nameU           U;\n    nameP           p;\n}\n"
        + FOOTER
    )


def precice_config(spec: CaseSpec) -> str:
    """``precice-config.xml`` (preCICE v3): the controller writes Velocity on its meshes."""
    meshes, fluid, controller, exchanges = [], [], [], []
    for name in spec.interfaces:
        cm, fm = mesh_name("Controller", name), mesh_name("Fluid", name)
        for m in (cm, fm):
            meshes.append(
                f'  <mesh name="{m}" dimensions="2">\n    <use-data name="Velocity" />\n  </mesh>'
            )
        fluid.append(f'    <provide-mesh name="{fm}" />')
        fluid.append(f'    <receive-mesh name="{cm}" from="Controller" />')
        fluid.append(f'    <read-data name="Velocity" mesh="{fm}" />')
        fluid.append(
            f'    <mapping:nearest-neighbor direction="read" from="{cm}" to="{fm}"'
            ' constraint="consistent" />'
        )
        controller.append(f'    <provide-mesh name="{cm}" />')
        controller.append(f'    <write-data name="Velocity" mesh="{cm}" />')
        exchanges.append(
            f'    <exchange data="Velocity" mesh="{cm}" from="Controller" to="Fluid" />'
        )
    # One window per action: serial-explicit with the controller first, so that the fluid
    # receives the window's action at its end and interpolates it linearly from the
    # previous one while it subcycles (parallel-explicit would apply it one window late).
    scheme = "serial-explicit" if spec.coupling == "action" else "parallel-explicit"
    data = (
        '  <data:vector name="Velocity" waveform-degree="1" />\n\n'
        if spec.coupling == "action"
        else '  <data:vector name="Velocity" />\n\n'
    )
    return (
        '<?xml version="1.0" encoding="UTF-8" ?>\n'
        "<!-- gymprecice tutorial case, written by gymprecice_tutorials.recipes -->\n"
        "<precice-configuration>\n"
        '  <log>\n    <sink filter="%Severity% > debug and %Rank% = 0"'
        ' format="---[precice] %ColorizedSeverity% %Message%" enabled="true" />\n  </log>\n\n'
        + data
        + "\n\n".join(meshes)
        + '\n\n  <participant name="Fluid">\n'
        + "\n".join(fluid)
        + '\n  </participant>\n\n  <participant name="Controller">\n'
        + "\n".join(controller)
        + "\n  </participant>\n\n"
        '  <m2n:sockets acceptor="Controller" connector="Fluid" exchange-directory=".." />\n\n'
        f"  <coupling-scheme:{scheme}>\n"
        '    <participants first="Controller" second="Fluid" />\n'
        f'    <max-time value="{foam_number(spec.episode_time)}" />\n'
        f'    <time-window-size value="{foam_number(spec.time_window)}" />\n'
        + "\n".join(exchanges)
        + f"\n  </coupling-scheme:{scheme}>\n</precice-configuration>\n"
    )


def gymprecice_config(spec: CaseSpec) -> dict[str, object]:
    """``gymprecice-config.json`` in the contract's explicit form."""
    return {
        "environment": {"name": spec.name},
        "precice": {"config_file": "precice-config.xml", "library": "precice"},
        "physics_simulation_engine": {
            "solvers": {
                "fluid": {
                    "kind": "openfoam",
                    "path": FLUID_DIR,
                    "participant": "Fluid",
                    "options": {
                        "prerun_end_time": spec.prerun_end_time,
                        **(
                            {"snapshots": list(spec.snapshots), "validation_fraction": 0.25}
                            if spec.snapshots
                            else {}
                        ),
                        **({"max_courant": spec.max_courant} if spec.max_courant else {}),
                    },
                }
            }
        },
        "controller": {
            "participant": "Controller",
            "write_to": {name: "Velocity" for name in spec.interfaces},
            "read_from": {},
            "meshes": {name: mesh_name("Controller", name) for name in spec.interfaces},
        },
        # one window per action: preCICE ramps between the written actions (waveform)
        "actions": (
            {"windows": 1, "scheme": "hold"}
            if spec.coupling == "action"
            else {"windows": spec.steps_per_action, "scheme": "ramp"}
        ),
    }


def adapter_files(spec: CaseSpec) -> dict[str, str]:
    """The OpenFOAM-preCICE adapter's files of the case (relative to ``fluid-openfoam/``)."""
    return {
        PRECICE_FO_FILE: adapter_function_object(),
        "system/preciceDict": precice_dict(spec),
    }
