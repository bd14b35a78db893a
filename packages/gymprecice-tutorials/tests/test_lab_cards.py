"""What the tutorials' lab cards make of the lab: Monitor columns, solver checks, the plugin.

The lab reads the tutorials through their cards alone; these pin the cards' effect where
an env's configuration or the import order could change it.
"""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from gymprecice_lab.common.registered_env import find_lab_env
from gymprecice_lab.common.requirements import missing_requirements
from gymprecice_lab.common.wrapped_env import episode_keywords

CYLINDERS = (
    "jet-cylinder",
    "rotating-cylinder",
    "jet-cylinder-fast",
    "rotating-cylinder-fast",
    "quickstart",
)


@pytest.mark.parametrize("name", CYLINDERS)
def test_the_cylinders_monitor_columns_stay_theirs(name: str) -> None:
    assert episode_keywords(find_lab_env(name).env_id) == ("mean_Cd", "mean_Cl", "action_rms")


@pytest.mark.parametrize(
    ("name", "keywords"),
    [
        ("perpendicular-flap-fast", ("mean_mean_tip_displacement", "action_rms")),
        ("two-flaps-fast", ("mean_mean_tip_displacement", "action_rms")),
        ("heated-plate", ("mean_tracking_error", "action_rms")),
    ],
)
def test_other_envs_record_their_own_objective(name: str, keywords: tuple[str, ...]) -> None:
    """No column of the cylinders' coefficients, NaN in every row, for a flap or a plate."""
    assert episode_keywords(find_lab_env(name).env_id) == keywords


def _report(*missing: str) -> dict:
    checks = [{"name": "pyprecice", "ok": True, "required": True}]
    checks += [{"name": name, "ok": False, "required": False} for name in missing]
    return {"checks": checks}


@pytest.mark.parametrize("name", ["perpendicular-flap", "perpendicular-flap-fast"])
def test_the_flaps_solver_checks_follow_the_solid(name: str) -> None:
    report = _report("deal.II library", "deal.II-preCICE adapter (elasticity)", "FEniCS")
    env = find_lab_env(name)
    dealii = [c["name"] for c in missing_requirements(report, env, {})]
    assert dealii == ["deal.II library", "deal.II-preCICE adapter (elasticity)"]
    fenics = [c["name"] for c in missing_requirements(report, env, {"solid": "fenics"})]
    assert fenics == ["FEniCS"]  # deal.II is not run: its absence does not count


def test_the_heated_plate_needs_fenics_only_with_the_fenics_plate() -> None:
    env = find_lab_env("heated-plate")
    report = _report("FEniCS solver environment")
    assert missing_requirements(report, env, {}) == []
    assert [c["name"] for c in missing_requirements(report, env, {"solid": "fenics"})] == [
        "FEniCS solver environment"
    ]


@pytest.mark.parametrize(
    "first",
    [
        "import gymprecice_tutorials.environments",
        "from gymprecice_tutorials.environments import ENVIRONMENTS",
        "import gymprecice_tutorials.plugin",
        "import gymprecice",
    ],
)
def test_any_import_order_registers_the_tutorials(first: str) -> None:
    """In a fresh process, whichever module comes first, every tutorial env is registered
    and no plugin warning is raised. Cost: about 2 s (one interpreter)."""
    code = (
        f"{first}\n"
        "import gymnasium, gymprecice\n"
        "from gymprecice_tutorials.environments import environments\n"
        "missing = [row[0] for row in environments() if row[0] not in gymnasium.registry]\n"
        "print('missing', missing)\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "GYMPRECICE_DISABLE_PLUGINS"}
    proc = subprocess.run(
        [sys.executable, "-W", "error::Warning", "-c", code],
        capture_output=True,
        text=True,
        timeout=300,
        env=env,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert proc.stdout.strip().splitlines()[-1] == "missing []", proc.stdout


def test_the_tutorials_plugin_imports_no_lab_module():
    """Loaded on every ``import gymprecice``: its cards come from core, its commands from
    the lab's own plugin."""
    code = (
        "import sys, importlib; importlib.import_module('gymprecice_tutorials.plugin'); "
        "print(sorted(m for m in sys.modules if m.startswith('gymprecice_lab')))"
    )
    env = {**os.environ, "GYMPRECICE_DISABLE_PLUGINS": "1"}
    proc = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, env=env
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "[]"
