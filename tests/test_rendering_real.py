"""``render_mode="rgb_array"`` on the real stack: each solver family hands over its field.

The doubles' rendering is tested in each package; these run the solvers themselves
(marked, and skipped naming what is missing, as the other real-stack tests; under
``GYMPRECICE_REQUIRE_REAL=1`` a skip fails). Checks as on the double: the frame's shape,
that it shows something, that it changes between two steps, and that the same env
without ``render_mode`` makes its solver write nothing more.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gymprecice_openfoam.testing import missing_coupled_stack

VARIANCE_FLOOR = 100.0


_MISSING = missing_coupled_stack("pimpleFoam")


def _quickstart(run_root: Path, **kwargs):
    from gymprecice_tutorials.quickstart.environment import QuickstartEnv

    short = {"prerun_end_time": 0.05, "actions_per_episode": 3}
    return QuickstartEnv(run_root=run_root, case_overrides=short, **kwargs)


def _files(root: Path) -> set[str]:
    return {
        str(p.relative_to(root))
        for p in root.rglob("*")
        if p.is_file() and ".gymprecice-openfoam" not in p.parts
    }


@pytest.mark.precice
@pytest.mark.openfoam
@pytest.mark.slow
@pytest.mark.timeout(600)
@pytest.mark.skipif(bool(_MISSING), reason="needs " + ", ".join(_MISSING))
def test_openfoam_renders_the_velocity_and_writes_nothing_without_render_mode(tmp_path):
    """Cost: two quickstart episodes of 3 actions on real pimpleFoam (about a minute on 2
    cores, most of it the two preparations with their 0.05 s pre-run)."""
    env = _quickstart(tmp_path / "rendering", render_mode="rgb_array")
    plain = _quickstart(tmp_path / "plain")
    try:
        env.reset(seed=0)
        first = env.render()
        # the env's width; the height from the channel's aspect, in whole macro blocks
        assert first.shape[1:] == (640, 3) and first.shape[0] % 16 == 0
        assert first.dtype == np.uint8
        assert first.var() > VARIANCE_FLOOR
        high = np.asarray(env.action_space.high, dtype=np.float32)
        env.step(high)
        env.step(high)
        second = env.render()
        assert np.abs(second.astype(int) - first.astype(int)).sum() > 0
        env.step(high)
        env.render()  # the last frame: the solver has exited, its files remain
        fluid = env.solver_dirs["fluid"]

        plain.reset(seed=0)
        truncated = False
        while not truncated:
            *_, truncated, _ = plain.step(high)
        plain_fluid = plain.solver_dirs["fluid"]
    finally:
        env.close()
        plain.close()
    control = (plain_fluid / "system" / "controlDict").read_text()
    assert "gymprecice_render" not in control
    extra = _files(fluid) - _files(plain_fluid)
    written = {name.split("/")[-1] for name in extra if not name.startswith("log")}
    # one U per action (and OpenFOAM's uniform/time beside it), nothing else
    assert written == {"U", "time"}, sorted(extra)
