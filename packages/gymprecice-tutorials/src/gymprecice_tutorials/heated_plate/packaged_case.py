"""The heated plate's packaged case, as files: one plate kept, the coupling's end time set.

Both the environment (:mod:`.environment`) and its test double (:mod:`.double`) build on
these files, so they live here, below both: the double takes the packaged case's
configuration and replaces the plate by its scripted one.
"""

from __future__ import annotations

import json
import re

from gymprecice_tutorials.heated_plate import CASE_DIR

__all__ = ["SOLIDS", "WINDOW", "case_files"]

#: preCICE time window (s): ten of them make one action
WINDOW = 0.01
#: solver directory of each plate
SOLIDS = {"openfoam": "solid-openfoam", "fenics": "solid-fenics"}


def case_files(solid: str, end_time: float) -> dict[str, str]:
    """The packaged case with one plate (``solid``) and the coupling ending at ``end_time``."""
    if solid not in SOLIDS:
        raise ValueError(f"solid must be one of {sorted(SOLIDS)}, got {solid!r}")
    keep = SOLIDS[solid]
    files: dict[str, str] = {}
    for path in sorted(CASE_DIR.rglob("*")):
        rel = path.relative_to(CASE_DIR).as_posix()
        top = rel.split("/", 1)[0]
        if not path.is_file() or (top in SOLIDS.values() and top != keep):
            continue
        files[rel] = path.read_text()
    config = json.loads(files["gymprecice-config.json"])
    config["environment"] = {"name": f"heated_plate-{solid}"}
    config["physics_simulation_engine"]["solvers"]["solid"] = {
        "kind": solid,
        "path": keep,
        "participant": "Solid",
    }
    files["gymprecice-config.json"] = json.dumps(config, indent=4) + "\n"
    files["precice-config.xml"] = re.sub(
        r'<max-time value="[^"]*" />',
        f'<max-time value="{end_time:.10g}" />',
        files["precice-config.xml"],
    )
    return files
