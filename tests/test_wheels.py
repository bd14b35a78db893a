"""Every distribution works from its wheel, with only pip, outside the repository.

The editable development install hides packaging mistakes (a case file left out of the
package data, an entry point or a dependency not declared), so these tests build real wheels
of the six distributions and install them, with pip alone and pip's configuration isolated
(``PIP_CONFIG_FILE=/dev/null``, ``--no-index --find-links`` on the wheelhouse), into fresh
virtual environments, and run the ``gymprecice`` command from a directory outside the
checkout, as a user who typed ``pip install gymprecice-openfoam`` would. The module takes
about 4 minutes on 2 cores (each test's cost is in its docstring).

Offline and fast: nothing is downloaded. The third-party dependencies come from this
environment (the one running the tests), but only those the wheels *declare*: the
declared requirements are followed through the installed metadata (extras and markers
evaluated), and exactly that closure is linked into a directory that the fresh
environment sees through a ``.pth`` file. pip then finds every dependency already
satisfied. A dependency a module imports but no wheel declares (``cloudpickle``, PyYAML)
is absent there, so the commands that need it fail here as they would for a user; and
torch is absent from the sets that must work without it. The wheelhouse holds only
gymprecice's own wheels, so pip can never choose to replace (and uninstall through the
links) a dependency of this environment.
"""

from __future__ import annotations

import email.parser
import json
import os
import shutil
import subprocess
import sys
import sysconfig
import venv
import zipfile
from importlib import metadata
from pathlib import Path

import pytest
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

ROOT = Path(__file__).resolve().parents[1]
DISTRIBUTIONS = [
    "gymprecice-core",
    "gymprecice-openfoam",
    "gymprecice-dealii",
    "gymprecice-fenics",
    "gymprecice-lab",
    "gymprecice-tutorials",
]
GPL = {"gymprecice-openfoam", "gymprecice-tutorials"}

pytestmark = pytest.mark.slow


# -- building -------------------------------------------------------------------------------------


#: a directory of already built wheels to test instead (scripts/release.sh: its dist/)
WHEELHOUSE_ENV = "GYMPRECICE_WHEELHOUSE"


@pytest.fixture(scope="module")
def wheelhouse(tmp_path_factory) -> Path:
    """One wheel per distribution, built from a clean copy (30 to 45 s on 2 cores), or
    the wheels in ``$GYMPRECICE_WHEELHOUSE`` (only wheels: pip must not build an sdist)."""
    out = tmp_path_factory.mktemp("wheelhouse")
    given = os.environ.get(WHEELHOUSE_ENV)
    if given:
        for wheel in Path(given).glob("*.whl"):
            shutil.copy(wheel, out)
        for dist in DISTRIBUTIONS:
            _wheel(out, dist)  # exactly one of each
        return out
    sources = tmp_path_factory.mktemp("sources")
    for dist in DISTRIBUTIONS:
        # setuptools' build/ directory in the source tree would otherwise carry files from
        # earlier builds into the wheel
        source = sources / dist
        shutil.copytree(
            ROOT / "packages" / dist,
            source,
            ignore=shutil.ignore_patterns("build", "*.egg-info", "__pycache__", "tests"),
        )
        subprocess.run(
            [
                *(sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation"),
                *("-q", "--disable-pip-version-check", "-w", str(out), str(source)),
            ],
            check=True,
            cwd=sources,
            env=_pip_env(),
        )
    return out


def _wheel(wheelhouse: Path, dist: str) -> Path:
    (wheel,) = wheelhouse.glob(dist.replace("-", "_") + "-*.whl")
    return wheel


def _wheel_metadata(wheel: Path) -> email.message.Message:
    with zipfile.ZipFile(wheel) as archive:
        name = next(n for n in archive.namelist() if n.endswith(".dist-info/METADATA"))
        return email.parser.Parser().parsestr(archive.read(name).decode())


# -- installing -----------------------------------------------------------------------------------


def _pip_env() -> dict[str, str]:
    """This environment, without pip's own configuration or anything pointing at the repo."""
    env = {
        k: v
        for k, v in os.environ.items()
        if not k.startswith(("PIP_", "GYMPRECICE_DISABLE"))
        and k not in ("PYTHONPATH", "VIRTUAL_ENV", "PYTHONHOME")
    }
    env.update(PIP_CONFIG_FILE=os.devnull, PIP_DISABLE_PIP_VERSION_CHECK="1", PYTHONNOUSERSITE="1")
    return env


def _requirements_of(requirement: Requirement, wheelhouse: Path) -> list[Requirement]:
    """What one requirement brings, with its extras, from a wheel or from this environment."""
    name = canonicalize_name(requirement.name)
    if name in DISTRIBUTIONS:
        declared = _wheel_metadata(_wheel(wheelhouse, name)).get_all("Requires-Dist") or []
    else:
        try:
            declared = metadata.requires(name) or []
        except metadata.PackageNotFoundError:
            pytest.fail(
                f"{requirement} is declared but not installed in the environment running the "
                "tests, so it cannot be offered offline; install it there"
            )
    wanted = []
    for line in declared:
        sub = Requirement(line)
        extras = [*sorted(requirement.extras), ""]
        if sub.marker is None or any(sub.marker.evaluate({"extra": e}) for e in extras):
            wanted.append(sub)
    return wanted


def _dependency_view(requirements: list[str], wheelhouse: Path, view: Path) -> list[str]:
    """Link the third-party closure of ``requirements`` into ``view``; returns its names."""
    todo = [Requirement(r) for r in requirements]
    seen: set[tuple[str, frozenset[str]]] = set()
    third_party: set[str] = set()
    while todo:
        requirement = todo.pop()
        key = (canonicalize_name(requirement.name), frozenset(requirement.extras))
        if key in seen:
            continue
        seen.add(key)
        if key[0] not in DISTRIBUTIONS:
            third_party.add(key[0])
        todo.extend(_requirements_of(requirement, wheelhouse))
    view.mkdir(parents=True)
    site = Path(sysconfig.get_paths()["purelib"])
    for name in sorted(third_party):
        dist = metadata.distribution(name)
        tops = {Path(str(f)).parts[0] for f in dist.files or []}
        tops |= set((dist.read_text("top_level.txt") or "").split())
        for top in tops - {"..", "__pycache__", "bin"}:
            # a top_level.txt name may be a module file: six -> six.py
            target = next((p for p in (site / top, site / f"{top}.py") if p.exists()), None)
            if target is not None and not (view / target.name).is_symlink():
                (view / target.name).symlink_to(target)
    return sorted(third_party)


class Installed:
    """A fresh virtual environment with some wheels installed by pip, used from ``cwd``."""

    def __init__(self, root: Path, wheelhouse: Path, requirements: list[str]) -> None:
        self.root = root
        self.env_dir = root / "venv"
        self.cwd = root / "elsewhere"  # outside the repository
        self.cwd.mkdir(parents=True)
        venv.EnvBuilder(with_pip=True).create(self.env_dir)
        self.python = self.env_dir / "bin" / "python"
        self.dependencies = _dependency_view(requirements, wheelhouse, root / "dependencies")
        purelib = subprocess.run(
            [str(self.python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
        (Path(purelib) / "gymprecice_test_dependencies.pth").write_text(
            str(root / "dependencies") + "\n"
        )
        self.env = _pip_env()
        self.env["PATH"] = os.pathsep.join([str(self.env_dir / "bin"), "/usr/bin", "/bin"])
        # Python < 3.12 seeds a venv with an old setuptools, which would shadow the linked
        # one that torch requires (>= 77); from an index pip would upgrade it
        subprocess.run(
            [str(self.python), "-m", "pip", "uninstall", "-q", "-y", "setuptools"],
            check=True,
            env=self.env,
        )
        subprocess.run(
            [
                *(str(self.python), "-m", "pip", "install", "-q", "--no-index"),
                *("--find-links", str(wheelhouse), *requirements),
            ],
            check=True,
            cwd=self.cwd,
            env=self.env,
        )

    def run(self, *argv: str, timeout: float = 300) -> subprocess.CompletedProcess[str]:
        return subprocess.run(
            [str(self.env_dir / "bin" / argv[0]), *argv[1:]],
            capture_output=True,
            text=True,
            cwd=self.cwd,
            env=self.env,
            timeout=timeout,
        )

    def python_says(self, code: str) -> str:
        proc = self.run("python", "-c", code)
        assert proc.returncode == 0, proc.stderr
        return proc.stdout.strip()

    def plugins(self) -> set[str]:
        proc = self.run("gymprecice", "plugins", "--json")
        assert proc.returncode == 0, proc.stderr
        listing = json.loads(proc.stdout)
        assert listing["failed"] == [], listing["failed"]
        return {p["name"] for p in listing["plugins"]}

    def written(self) -> list[str]:
        return sorted(p.name for p in self.cwd.iterdir())


def _one_line(proc: subprocess.CompletedProcess[str], install: str) -> None:
    """A missing extra: exit 2, one line on stderr naming the install, no traceback."""
    assert proc.returncode == 2, (proc.returncode, proc.stdout, proc.stderr)
    assert proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert f"pip install '{install}'" in proc.stderr, proc.stderr


_IMPORT_ERROR = "try:\n    import {0}\nexcept ModuleNotFoundError as exc:\n    print(exc)\n"


# -- the wheels -----------------------------------------------------------------------------------


def test_wheels_carry_code_data_entry_points_licence_and_metadata(wheelhouse: Path) -> None:
    """Reads the six wheels (no install; the build is the module's fixture)."""
    for dist in DISTRIBUTIONS:
        wheel = _wheel(wheelhouse, dist)
        with zipfile.ZipFile(wheel) as archive:
            names = archive.namelist()
            entry_points = next(n for n in names if n.endswith("entry_points.txt"))
            text = archive.read(entry_points).decode()
            licences = [n for n in names if "/licenses/" in n]
            assert licences, f"{dist}: no licence file in the wheel"
            licence = archive.read(licences[0]).decode()
        assert "[gymprecice]" in text, dist
        meta = _wheel_metadata(wheel)
        expected = "GPL-3.0-or-later" if dist in GPL else "MIT"
        assert meta["License-Expression"] == expected, dist
        assert ("GNU GENERAL PUBLIC LICENSE" in licence) == (dist in GPL), dist
        assert meta.get_all("Classifier"), f"{dist}: no classifiers"
        assert len(meta.get_payload()) > 1500, f"{dist}: its README is not an index page"
        if dist == "gymprecice-core":
            assert "gymprecice = gymprecice.cli:main" in text
            assert "gymprecice/plugin/hookspecs.py" in names
            assert "gymprecice/old_paths.py" in names
            assert "gymprecice/testing/fake_precice/participant.py" in names
            assert "gymprecice/testing/fake_precice/schemes/base.py" in names
            requires = " ".join(meta.get_all("Requires-Dist") or [])
            assert "cloudpickle" in requires
            assert 'stable-baselines3>=2.3; extra == "sb3"' in requires
            assert 'pytest>=7; extra == "testing"' in requires
        if dist == "gymprecice-lab":
            requires = " ".join(meta.get_all("Requires-Dist") or [])
            assert "PyYAML" in requires and "torch>=2.8" in requires
        if dist == "gymprecice-tutorials":
            # the ids, declared in the metadata (registered before any plugin module loads)
            assert "[gymprecice.environments]" in text
            assert "gymprecice/JetCylinderFast-v0 = gymprecice_tutorials.fast_cases:" in text
            cases = [n for n in names if "/cases/" in n]
            assert any(n.endswith("precice-config.xml") for n in cases)
            assert any(n.endswith("gymprecice-config.json") for n in cases)
            assert any(n.endswith("blockMeshDict") or n.endswith("recipes.py") for n in names)
            flap = "gymprecice_tutorials/perpendicular_flap/case/"
            assert flap + "solid-dealii/parameters.prm" in names
            assert flap + "solid-fenics/solid.py" in names
            assert flap + "fluid-openfoam/system/preciceDict" in names
            plate = "gymprecice_tutorials/heated_plate/case/"
            assert plate + "solid-fenics/solid.py" in names
            assert plate + "solid-openfoam/system/preciceDict" in names
            assert any("/policies/" in n and n.endswith("model.zip") for n in names)
        if dist == "gymprecice-fenics":
            # run by the FEniCS interpreter from the installed package, so it must ship
            assert "gymprecice_fenics/dry_run.py" in names


# -- install sets ---------------------------------------------------------------------------------


def test_core_alone(wheelhouse: Path, tmp_path: Path) -> None:
    """gymprecice-core by itself: 20 to 45 s on 2 cores (a venv, one install, six commands)."""
    env = Installed(tmp_path, wheelhouse, ["gymprecice-core"])
    assert "torch" not in env.dependencies and "stable-baselines3" not in env.dependencies
    assert env.plugins() == {"script"}
    doctor = env.run("gymprecice", "doctor")
    assert doctor.returncode in (0, 1) and "python" in doctor.stdout, doctor.stderr
    assert "gymprecice package" not in doctor.stdout  # no clash: the wheel owns the package
    _one_line(env.run("gymprecice", "train", "jet-cylinder-fast", "--double"), "gymprecice-lab")
    assert (
        "--index-url https://download.pytorch.org/whl/cpu"
        in env.run("gymprecice", "train", "x").stderr
    )
    said = env.python_says(_IMPORT_ERROR.format("gymprecice.sb3"))
    assert said.startswith("gymprecice.sb3 needs stable_baselines3")
    assert "pip install 'gymprecice-core[sb3]'" in said
    said = env.python_says(_IMPORT_ERROR.format("gymprecice.testing.conformance"))
    assert "pip install 'gymprecice-core[testing]'" in said
    assert env.written() == []


def test_core_and_openfoam_without_torch(wheelhouse: Path, tmp_path: Path) -> None:
    """gymprecice-openfoam (brings core), no torch: about 25 s on 2 cores."""
    env = Installed(tmp_path, wheelhouse, ["gymprecice-openfoam"])
    assert "torch" not in env.dependencies
    assert env.python_says(_IMPORT_ERROR.format("torch")) == "No module named 'torch'"
    assert env.plugins() == {"script", "openfoam"}
    doctor = env.run("gymprecice", "doctor")
    assert doctor.returncode in (0, 1) and "OpenFOAM" in doctor.stdout, doctor.stderr
    assert "setup.sh" not in doctor.stdout
    _one_line(env.run("gymprecice", "evaluate", "jet-cylinder-fast"), "gymprecice-lab")
    assert env.written() == []


def test_tutorials_without_the_training_extra(wheelhouse: Path, tmp_path: Path) -> None:
    """gymprecice-tutorials alone (four plugins, no lab, no torch): 20 to 30 s on 2 cores."""
    env = Installed(tmp_path, wheelhouse, ["gymprecice-tutorials"])
    assert "torch" not in env.dependencies
    assert env.plugins() == {"script", "openfoam", "dealii", "fenics", "tutorials"}
    ids = env.python_says(
        "import gymnasium, gymprecice; "
        "print(sorted(i for i in gymnasium.registry if i.startswith('gymprecice/')))"
    )
    assert "gymprecice/JetCylinderFast-v0" in ids
    proc = env.run("gymprecice", "evaluate", "jet-cylinder-fast", "--double", "--policy", "shipped")
    _one_line(proc, "gymprecice-tutorials[train]")
    assert env.written() == []  # nothing written, ./runs included


@pytest.mark.timeout(900)
def test_tutorials_with_the_training_extra(wheelhouse: Path, tmp_path: Path) -> None:
    """gymprecice-tutorials[train] (the lab, SB3, CPU torch): evaluate the shipped policy
    and train on the test double. 1 to 2 minutes on 2 cores (the install about 20 s,
    evaluate and train about 30 s each)."""
    env = Installed(tmp_path, wheelhouse, ["gymprecice-tutorials[train]"])
    assert {"torch", "stable-baselines3", "pyyaml"} <= set(env.dependencies)
    assert env.plugins() == {"script", "openfoam", "dealii", "fenics", "tutorials", "lab"}
    package = Path(env.python_says("import gymprecice_tutorials as t; print(t.__file__)"))
    assert ROOT not in package.parents  # the installed copy, not the checkout
    doctor = env.run("gymprecice", "doctor")
    assert doctor.returncode in (0, 1) and "pyprecice" in doctor.stdout, doctor.stderr

    evaluate = env.run(
        *("gymprecice", "evaluate", "jet-cylinder-fast", "--double", "--policy", "shipped"),
        *("--episode-time", "0.2", "--out", "evaluate"),
    )
    assert evaluate.returncode == 0, evaluate.stdout + evaluate.stderr
    summary = json.loads((env.cwd / "evaluate" / "summary.json").read_text())
    assert summary

    shutil.copy(ROOT / "scripts" / "ppo-fast.yml", env.cwd / "ppo-fast.yml")
    train = env.run(
        *("gymprecice", "train", "jet-cylinder-fast", "--double", "--hyperparams"),
        *("ppo-fast.yml", "--n-envs", "1", "--timesteps", "16", "--n-steps", "8"),
        *("--batch-size", "8", "--episode-time", "0.2", "--out", "train", "--no-progress-bar"),
        timeout=600,
    )
    assert train.returncode == 0, train.stdout + train.stderr
    assert (env.cwd / "train" / "model.zip").is_file()
    assert (env.cwd / "train" / "hyperparams.yaml").is_file()
