"""Each distribution builds a wheel that installs and works outside the repository.

The editable development install hides packaging mistakes (a case file left out of the
package data, an entry point not declared), so this test builds real wheels, installs them
into a fresh virtual environment, and uses them from a directory outside the checkout.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import venv
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DISTRIBUTIONS = [
    "gymprecice-core",
    "gymprecice-openfoam",
    "gymprecice-dealii",
    "gymprecice-fenics",
    "gymprecice-tutorials",
]

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def wheels(tmp_path_factory) -> dict[str, Path]:
    out = tmp_path_factory.mktemp("wheels")
    built = {}
    for dist in DISTRIBUTIONS:
        # build from a clean copy: setuptools' build/ directory in the source tree would
        # otherwise carry files from earlier builds into the wheel
        source = out / "src" / dist
        shutil.copytree(
            ROOT / "packages" / dist,
            source,
            ignore=shutil.ignore_patterns("build", "*.egg-info", "__pycache__", "tests"),
        )
        subprocess.run(
            [
                sys.executable,
                "-m",
                "pip",
                "wheel",
                "--no-deps",
                "--no-build-isolation",
                "-q",
                "-w",
                str(out),
                str(source),
            ],
            check=True,
            cwd=out,
        )
        (wheel,) = out.glob(dist.replace("-", "_") + "-*.whl")
        built[dist] = wheel
    return built


def test_wheels_carry_their_code_data_and_entry_points(wheels: dict[str, Path]) -> None:
    for dist, wheel in wheels.items():
        with zipfile.ZipFile(wheel) as archive:
            names = archive.namelist()
            entry_points = next(n for n in names if n.endswith("entry_points.txt"))
            text = archive.read(entry_points).decode()
        assert "[gymprecice]" in text, dist
        if dist == "gymprecice-core":
            assert "gymprecice = gymprecice.cli:main" in text
            assert "gymprecice/hookspecs.py" in names
            assert "gymprecice/testing/fake_precice/participant.py" in names
            assert "gymprecice/testing/fake_precice/schemes/base.py" in names
        if dist == "gymprecice-tutorials":
            cases = [n for n in names if "/cases/" in n]
            assert any(n.endswith("precice-config.xml") for n in cases)
            assert any(n.endswith("gymprecice-config.json") for n in cases)
            assert any(n.endswith("blockMeshDict") or n.endswith("recipes.py") for n in names)
            flap = "gymprecice_tutorials/perpendicular_flap/case/"
            assert flap + "solid-dealii/parameters.prm" in names
            assert flap + "fluid-openfoam/system/preciceDict" in names
            plate = "gymprecice_tutorials/heated_plate/case/"
            assert plate + "solid-fenics/solid.py" in names
            assert plate + "solid-openfoam/system/preciceDict" in names
        if dist == "gymprecice-fenics":
            # run by the FEniCS interpreter from the installed package, so it must ship
            assert "gymprecice_fenics/dry_run.py" in names


def test_wheels_install_into_a_fresh_venv_and_work_outside_the_repo(wheels, tmp_path: Path) -> None:
    env_dir = tmp_path / "venv"
    venv.EnvBuilder(with_pip=True).create(env_dir)
    python = env_dir / "bin" / "python"
    # torch is not needed by these distributions without the [train] extra.
    subprocess.run(
        [
            str(python),
            "-m",
            "pip",
            "install",
            "-q",
            "--disable-pip-version-check",
            *map(str, wheels.values()),
        ],
        check=True,
    )
    outside = tmp_path / "elsewhere"
    outside.mkdir()
    clean_env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    listing = subprocess.run(
        [str(env_dir / "bin" / "gymprecice"), "plugins", "--json"],
        check=True,
        capture_output=True,
        text=True,
        cwd=outside,
        env=clean_env,
    )
    names = json.dumps(json.loads(listing.stdout))
    for plugin in ("openfoam", "dealii", "fenics", "script"):
        assert plugin in names
    probe = subprocess.run(
        [
            str(python),
            "-c",
            "import gymnasium, gymprecice, gymprecice_tutorials, pathlib;"
            "ids = [i for i in gymnasium.registry if i.startswith('gymprecice/')];"
            "print(sorted(ids));"
            "print(pathlib.Path(gymprecice_tutorials.__file__).parent)",
        ],
        check=True,
        capture_output=True,
        text=True,
        cwd=outside,
        env=clean_env,
    )
    ids_line, package_dir = probe.stdout.strip().splitlines()[-2:]
    assert "gymprecice/JetCylinder-v0" in ids_line
    assert str(ROOT) not in package_dir  # the installed copy, not the checkout
    assert list(Path(package_dir).rglob("precice-config.xml"))
