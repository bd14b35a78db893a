"""HeatedPlateFast-v0: the heated plate's training case, the same task on a cheaper flow.

HeatedPlate-v0 costs about 57 s per 2.3 s episode on 2 cores, almost all of it the fluid
(12,013 cells, 230 windows of 0.01 s, two coupling iterations per window): an hour of
training would be about 60 episodes. The training case keeps the task, the plate, the
time window, the observation, the action, the reward and the starts, and makes the flow
cheaper with two measured edits (docs/training.md, "The heated plate"):

* the fluid mesh with a quarter of the cells in each direction of each block (12,013 ->
  825 cells; the plate's interface has 41 faces instead of 161);
* serial-explicit Fluid-Solid coupling instead of serial-implicit with Aitken (one
  solve of each participant per window; the tutorial's partitioned-flow variant couples
  this plate explicitly too).

An episode then costs about 3.5 s. Windows of 0.05 s would save little more (process
start and settling dominate) but lag the heater's step by up to 1.8 K.

A policy trained here is evaluated on HeatedPlate-v0 itself, with either plate: the
interface temperature of the training case follows the full case's within
:data:`AGREEMENT_K` over an episode, uncontrolled or with a heater step (measured,
``benchmarks/bench_heated_plate_training_case.py``). The plate is
OpenFOAM's laplacianFoam; the FEniCS plate is for HeatedPlate-v0.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from gymprecice_tutorials.heated_plate.environment import HeatedPlateEnv, case_files

__all__ = ["AGREEMENT_K", "FAST_CELLS", "FAST_WINDOW", "HeatedPlateFastEnv", "fast_case_files"]

#: the training case's fluid blocks (cells along x and y of the three blocks)
FAST_CELLS = ((21, 11), (41, 11), (13, 11))
#: the training case's time window (s), HeatedPlate-v0's: an action (0.1 s) spans ten
FAST_WINDOW = 0.01
#: the largest difference (K) between the training case's and HeatedPlate-v0's mean
#: interface temperature over an episode, uncontrolled (0.011 K) or with the heater
#: stepped to 330 K (0.22 K, during the step's first 0.2 s); measured, docs/training.md
AGREEMENT_K = 0.25

_FULL_CELLS = ((81, 41), (161, 41), (51, 41))
_IMPLICIT = re.compile(
    r"<coupling-scheme:serial-implicit>.*?</coupling-scheme:serial-implicit>", re.DOTALL
)


def _replace_once(text: str, old: str, new: str, where: str) -> str:
    """``text`` with ``old`` replaced, failing loudly when the packaged case changed."""
    if text.count(old) != 1:
        raise RuntimeError(
            f"the heated plate's training case expects {old!r} exactly once in {where}; "
            "the packaged case changed: update gymprecice_tutorials.heated_plate.fast"
        )
    return text.replace(old, new)


def fast_case_files(
    end_time: float,
    *,
    cells: tuple[tuple[int, int], ...] = FAST_CELLS,
    window: float = FAST_WINDOW,
    explicit: bool = True,
) -> dict[str, str]:
    """The training case's files: HeatedPlate-v0's case (OpenFOAM plate) with the edits
    of the module docstring; the keywords exist to measure each edit (and a longer window)
    on its own, as ``benchmarks/bench_heated_plate_training_case.py`` does."""
    files = case_files("openfoam", end_time)
    mesh = "fluid-openfoam/system/blockMeshDict"
    for (fx, fy), (nx, ny) in zip(_FULL_CELLS, cells, strict=True):
        files[mesh] = _replace_once(files[mesh], f"({fx} {fy} 1)", f"({nx} {ny} 1)", mesh)
    steps = 0.1 / window
    if abs(steps - round(steps)) > 1e-9:
        raise ValueError(f"window must divide the action's 0.1 s, got {window}")
    for rel in ("fluid-openfoam/system/controlDict", "solid-openfoam/system/controlDict"):
        files[rel] = _replace_once(
            files[rel], "deltaT          0.01;", f"deltaT          {window:g};", rel
        )
    config = files["precice-config.xml"]
    config = config.replace(
        '<time-window-size value="0.01" />', f'<time-window-size value="{window:g}" />'
    )
    if explicit:
        config = _replace_once(
            config,
            "(serial-implicit, Aitken, time windows of 0.01 s)",
            f"in HeatedPlate-v0; this training case couples them serial-explicit in windows "
            f"of {window:g} s",
            "precice-config.xml",
        )
        (block,) = _IMPLICIT.findall(config)
        exchanges = "\n".join(
            line for line in block.splitlines() if "<participants" in line or "<exchange" in line
        )
        max_time = re.search(r'<max-time value="[^"]*" />', block)
        assert max_time is not None
        config = config.replace(
            block,
            "<coupling-scheme:serial-explicit>\n"
            f'    <time-window-size value="{window:g}" />\n'
            f"    {max_time.group(0)}\n"
            f"{exchanges}\n"
            "  </coupling-scheme:serial-explicit>",
        )
    files["precice-config.xml"] = config
    files["gymprecice-config.json"] = _replace_once(
        files["gymprecice-config.json"],
        '"windows": 10',
        f'"windows": {round(steps)}',
        "gymprecice-config.json",
    )
    return files


class HeatedPlateFastEnv(HeatedPlateEnv):
    """HeatedPlate-v0 on the training case (module docstring): same spaces, reward, starts.

    ``solid`` is fixed to ``"openfoam"``; ``double=True`` runs the same lumped plate as
    HeatedPlate-v0's double (the task's test double does not depend on the mesh).
    """

    def __init__(
        self,
        options: Mapping[str, Any] | str | Path | None = None,
        idx: int = 0,
        *,
        solid: str = "openfoam",
        **kwargs: Any,
    ) -> None:
        if solid != "openfoam":
            raise ValueError(
                "HeatedPlateFast-v0 trains on the OpenFOAM plate only; evaluate a policy on "
                f"the FEniCS plate with HeatedPlate-v0 (solid='fenics'), got solid={solid!r}"
            )
        super().__init__(options, idx, solid=solid, **kwargs)

    def packaged_case(self, end_time: float) -> tuple[str, dict[str, str]]:
        return "heated-plate-fast", fast_case_files(end_time)
