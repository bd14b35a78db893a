"""How the recipes write OpenFOAM dictionaries: banner, header, numbers and vectors.

Numbers are written with ten significant digits and never as ``-0``, so a case written
twice from the same recipe is the same byte for byte (the packaged cases are checked
against their recipe).
"""

from __future__ import annotations

BANNER = """\
/*--------------------------------*- C++ -*----------------------------------*\\
  gymprecice tutorial case, written by gymprecice_tutorials.recipes:
  change the recipe and regenerate rather than editing this file.
\\*---------------------------------------------------------------------------*/
"""
FOOTER = "\n// ************************************************************************* //\n"


def foam_header(cls: str, location: str, obj: str) -> str:
    return (
        BANNER
        + "FoamFile\n{\n    version     2.0;\n    format      ascii;\n"
        + f'    class       {cls};\n    location    "{location}";\n    object      {obj};\n}}\n\n'
    )


def boundary_field(entries: dict[str, str]) -> str:
    lines = ["boundaryField", "{"]
    for name, body in entries.items():
        lines.append(f"    {name}")
        lines.append("    {")
        for stmt in body.strip().split("\n"):
            lines.append(f"        {stmt.strip()}")
        lines.append("    }")
    lines.append("}")
    return "\n".join(lines) + "\n"


def foam_number(x: float) -> str:
    text = f"{x:.10g}"
    return "0" if text == "-0" else text


def foam_vector(*xs: float) -> str:
    return "(" + " ".join(foam_number(x) for x in xs) + ")"
