"""The flap's packaged case, as files, with one of its two solids.

``case/`` holds both solids of the same flap: ``solid-dealii/`` (the deal.II-preCICE
adapter's ``elasticity``, what ``case/gymprecice-config.json`` names) and
``solid-fenics/`` (a FEniCS script coupled through fenicsprecice, run by the
gymprecice-fenics plugin). Both are preCICE participant ``Solid`` on ``Solid-Mesh``, so
one ``precice-config.xml`` serves either; :func:`case_files` keeps one solid's directory
and points the solver ``solid`` of ``gymprecice-config.json`` at it (the deal.II case's
files are the packaged ones, unchanged). PerpendicularFlap-v0 (:mod:`.environment`) and
its training case (:mod:`.training_case`) build on these files.
"""

from __future__ import annotations

from gymprecice_tutorials.perpendicular_flap import CASE_DIR

__all__ = ["SOLIDS", "case_files"]

#: solver directory of each solid (the solver kind is the key)
SOLIDS = {"dealii": "solid-dealii", "fenics": "solid-fenics"}


def check_solid(solid: str) -> str:
    """``solid`` when it names one of :data:`SOLIDS`; a ``ValueError`` naming them otherwise."""
    if solid not in SOLIDS:
        raise ValueError(f"solid must be one of {sorted(SOLIDS)}, got {solid!r}")
    return solid


def case_files(solid: str = "dealii") -> dict[str, str]:
    """The packaged case's files (relative path -> text) with the solid ``solid`` only."""
    keep = SOLIDS[check_solid(solid)]
    files: dict[str, str] = {}
    for path in sorted(CASE_DIR.rglob("*")):
        rel = path.relative_to(CASE_DIR).as_posix()
        top = rel.split("/", 1)[0]
        if not path.is_file() or "__pycache__" in rel or (top in SOLIDS.values() and top != keep):
            continue
        files[rel] = path.read_text()
    if solid != "dealii":
        config = "gymprecice-config.json"
        files[config] = _replace_once(
            files[config],
            '"solid": {"kind": "dealii", "path": "solid-dealii", "participant": "Solid"}',
            f'"solid": {{"kind": "{solid}", "path": "{keep}", "participant": "Solid"}}',
            config,
        )
    return files


def _replace_once(text: str, old: str, new: str, where: str) -> str:
    """``text`` with ``old`` replaced, failing loudly when the packaged case changed."""
    if text.count(old) != 1:
        raise ValueError(
            f"{CASE_DIR / where}: expected {old!r} exactly once to swap the solid; update "
            "gymprecice_tutorials.perpendicular_flap.packaged_case to the packaged case"
        )
    return text.replace(old, new)
