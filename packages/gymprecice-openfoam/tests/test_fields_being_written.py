"""A field file that OpenFOAM is still writing is asked for again, never parsed.

foamlib's parser can take minutes on a file cut short in the middle of a list (measured:
over 20 s on 1.5 kB of a 36 kB velocity field), so ``env.render()`` would stall on the
frame OpenFOAM writes while the env reads it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gymprecice_openfoam import fields

HEADER = """FoamFile
{
    version     2.0;
    format      ascii;
    class       volVectorField;
    object      U;
}
// * * * * * * * * * * * * * * * * * * * * * * * * * * * * * * * * * * * * * //

dimensions      [0 1 -1 0 0 0 0];

internalField   nonuniform List<vector>
"""
FOOTER = "boundaryField\n{\n}\n\n\n// ************************************************************************* //\n"


def _field(n: int) -> str:
    rows = "\n".join(f"({0.1 * k:.7g} {-0.01 * k:.7g} 2.7241947e-22)" for k in range(n))
    return f"{HEADER}{n}\n(\n{rows}\n)\n;\n\n{FOOTER}"


@pytest.mark.timeout(60)
def test_a_field_cut_short_is_being_written_and_a_whole_one_is_read(tmp_path: Path) -> None:
    path = tmp_path / "U"
    text = _field(400)
    path.write_text(text[: len(text) // 3].rsplit("e-", 1)[0] + "e-")  # cut inside a number
    with pytest.raises(ValueError, match="being written"):
        fields._values(path, 400)
    path.write_text(text)
    values = fields._values(path, 400)
    assert values.shape == (400, 3)
    np.testing.assert_allclose(values[-1, :2], [39.9, -3.99])
