"""``gymprecice new``: the package it writes installs, registers and runs on the test double.

The fast tests call the command in this process (stdin is not a terminal under pytest, so
it asks nothing) and look at what it wrote or refused. The slow ones install what it wrote
with pip (``--target``, no dependencies, no index: everything it needs is in this
environment) and run the new package's own tests against it, as its author would after
``pip install -e``.
"""

from __future__ import annotations

import io
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from gymprecice.plugin.hookspecs import hookimpl
from gymprecice.plugin.manager import temporary_plugin
from gymprecice.scaffold import available_kinds, package_files, plan_package
from gymprecice.tools.cli import main

#: seconds a pip install or a package's own tests may take before the test fails
COMMAND_TIMEOUT = 480
KNOWN_PLUGIN_KINDS = ("openfoam", "dealii", "fenics")


def new(capsys, *argv: str) -> tuple[int, str, str]:
    """``gymprecice new ARGV``: its status, stdout and stderr."""
    status = main(["new", *argv])
    out, err = capsys.readouterr()
    return status, out, err


@pytest.fixture(autouse=True)
def no_terminal(monkeypatch: pytest.MonkeyPatch) -> None:
    """stdin is not a terminal: the command asks nothing."""
    monkeypatch.setattr(sys, "stdin", io.StringIO(""))


def tree(root: Path) -> list[str]:
    return sorted(str(p.relative_to(root)) for p in root.rglob("*"))


# -- the default package ----------------------------------------------------------------------


def test_the_default_package_is_written_and_its_case_passes_check(tmp_path, capsys) -> None:
    target = tmp_path / "my-env"
    status, out, err = new(capsys, "my-env", "--dir", str(target))
    assert status == 0, err
    assert "registers my-env/MyEnv-v0 (short name my-env)" in out
    assert "gymprecice train my-env/MyEnv-v0 --double --timesteps 80" in out
    files = set(tree(target))
    for path in (
        "pyproject.toml",
        "README.md",
        "src/my_env/__init__.py",
        "src/my_env/plugin.py",
        "src/my_env/env.py",
        "src/my_env/case/gymprecice-config.json",
        "src/my_env/case/precice-config.xml",
        "src/my_env/case/solver/solver.py",
        "tests/test_env.py",
    ):
        assert path in files, sorted(files)
    pyproject = (target / "pyproject.toml").read_text()
    assert '[project.entry-points.gymprecice]\nmy-env = "my_env.plugin"' in pyproject
    declared = '[project.entry-points."gymprecice.environments"]\n"my-env/MyEnv-v0" = '
    assert declared + '"my_env.env:MyEnv"' in pyproject
    assert '"gymprecice-core>=' in pyproject
    env = (target / "src/my_env/env.py").read_text()
    assert "class MyEnv(Adapter):" in env
    for method in ("_get_action", "_get_observation", "_get_reward", "_close_external_resources"):
        assert f"def {method}(" in env
    assert "gym.spaces.Box(-1.0, 1.0, shape=(n,)" in env and "DISCRETE = False" in env
    assert main(["check", str(target / "src/my_env/case")]) == 0


def test_the_written_python_is_lint_clean(tmp_path) -> None:
    """Every kind's files pass ruff with its default settings (and the import order a
    package of its own has), as a new package's author's own checks would run it."""
    ruff = shutil.which("ruff", path=str(Path(sys.executable).parent)) or shutil.which("ruff")
    if ruff is None:
        pytest.skip("ruff is not installed")
    for kind in ("command", *[k for k in KNOWN_PLUGIN_KINDS if k in available_kinds()]):
        pkg = plan_package(f"lint-{kind}", kind, "discrete" if kind == "dealii" else "box", 3)
        root = tmp_path / pkg.name
        for relative, text in package_files(pkg).items():
            (root / relative).parent.mkdir(parents=True, exist_ok=True)
            (root / relative).write_text(text)
        for argv in (
            ["check", "--isolated", "--select", "E,F,W,I,B,UP,SIM", "."],
            ["format", "--isolated", "--check", "."],
        ):
            proc = subprocess.run([ruff, *argv], cwd=root, capture_output=True, text=True)
            assert proc.returncode == 0, f"{kind}: ruff {argv[0]}\n{proc.stdout}{proc.stderr}"


@pytest.mark.parametrize("kind", KNOWN_PLUGIN_KINDS)
def test_a_plugin_kinds_case_passes_check(kind: str, tmp_path, capsys) -> None:
    if kind not in available_kinds():
        pytest.skip(f"no plugin of kind {kind} is installed")
    target = tmp_path / f"{kind}-env"
    status, out, err = new(capsys, f"{kind}-env", "--kind", kind, "--dir", str(target))
    assert status == 0, err
    module = f"{kind}_env"
    assert f"solver: kind {kind}" in out
    assert (target / f"src/{module}/case/stand-in/solver.py").is_file()
    assert f'"gymprecice-{kind}>=' in (target / "pyproject.toml").read_text()
    assert main(["check", str(target / f"src/{module}/case")]) == 0, capsys.readouterr()


class _ToyPlugin:
    """A third-party plugin's kind, which ``gymprecice new`` knows nothing about."""

    @staticmethod
    @hookimpl
    def gymprecice_solver_kinds() -> dict[str, str]:
        return {"toy": "a toy solver"}


def test_a_third_party_kind_gets_a_folder_to_fill_and_the_stand_in(tmp_path, capsys) -> None:
    with temporary_plugin(_ToyPlugin(), "toy-plugin"):
        assert "toy" in available_kinds() and "script" not in available_kinds()
        target = tmp_path / "toy-env"
        status, out, err = new(capsys, "toy-env", "--kind", "toy", "--dir", str(target))
        assert "registers toy-env/ToyEnv-v0" in out
    assert status == 0, err
    case = target / "src/toy_env/case"
    assert "kind `toy`" in (case / "solver/README.md").read_text()
    assert (case / "stand-in/solver.py").is_file()
    assert '"kind": "toy"' in (case / "gymprecice-config.json").read_text()
    assert "STAND_IN: dict[str, Any] | None = {" in (target / "src/toy_env/env.py").read_text()


# -- what is refused ---------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("argv", "said"),
    [
        (["9lives"], "not a Python name"),
        (["my env"], "is not a package name"),
        (["-bad-"], None),  # argparse takes it for an option: still a usage error
        (["class"], "a Python keyword"),
        (["numpy"], "would shadow"),
        (["my-env", "--kind", "no-such-kind"], "unknown solver kind 'no-such-kind'"),
        (["my-env", "--kind", "script"], "kind 'script'"),
        (["my-env", "--actuator", "wheel"], "unknown actuator 'wheel'"),
        (["my-env", "--actuators", "0"], "--actuators takes 1 to"),
        (["my-env", "--kind", "openfoam", "--solver-plugin"], "--solver-plugin"),
        ([], "NAME is needed"),
    ],
)
def test_bad_input_is_refused_in_one_line_and_writes_nothing(
    argv: list[str], said: str | None, tmp_path, capsys, monkeypatch
) -> None:
    monkeypatch.chdir(tmp_path)
    if argv[:1] == ["-bad-"]:
        with pytest.raises(SystemExit) as exit_:
            main(["new", *argv])
        assert exit_.value.code == 2
        capsys.readouterr()
    else:
        status, out, err = new(capsys, *argv)
        assert status == 2 and not out
        assert len(err.strip().splitlines()) == 1, err
        assert err.startswith("gymprecice new: error: ") and said in err, err
    assert not list(tmp_path.iterdir())


def test_an_existing_folder_is_refused_without_force(tmp_path, capsys) -> None:
    target = tmp_path / "my-env"
    target.mkdir()
    (target / "notes.txt").write_text("mine\n")
    (target / "README.md").write_text("my own readme\n")
    status, out, err = new(capsys, "my-env", "--dir", str(target))
    assert status == 1 and not out
    assert len(err.strip().splitlines()) == 1 and "--force" in err, err
    assert tree(target) == ["README.md", "notes.txt"]
    assert (target / "README.md").read_text() == "my own readme\n"
    assert [p.name for p in tmp_path.iterdir()] == ["my-env"]  # no staging folder left
    status, out, err = new(capsys, "my-env", "--dir", str(target), "--force")
    assert status == 0, err
    assert (target / "notes.txt").read_text() == "mine\n"  # not the package's: left alone
    assert "MyEnv-v0" in (target / "README.md").read_text()
    assert (target / "src/my_env/env.py").is_file()


def test_on_a_terminal_it_asks_for_what_the_options_leave_out(
    tmp_path, capsys, monkeypatch
) -> None:
    """A bad answer is said and asked again; an empty one takes the default."""
    if "dealii" not in available_kinds():
        pytest.skip("no plugin of kind dealii is installed")
    terminal = io.StringIO("")
    terminal.isatty = lambda: True  # type: ignore[method-assign]
    monkeypatch.setattr(sys, "stdin", terminal)
    answers = iter(["9lives", "flap-env", "nosuch", "dealii", "", "0", "2"])
    questions: list[str] = []

    def ask(question: str) -> str:
        questions.append(question)
        return next(answers)

    monkeypatch.setattr("builtins.input", ask)
    status, out, err = new(capsys, "--dir", str(tmp_path / "flap"))
    assert status == 0, err
    assert len(questions) == 7 and questions[0].startswith("Package name")
    assert "not a Python name" in err and "choose one of" in err and "1 to 64" in err
    assert "registers flap-env/FlapEnv-v0" in out and "kind dealii" in out
    env = (tmp_path / "flap/src/flap_env/env.py").read_text()
    assert "DISCRETE = False" in env  # the empty answer: box
    assert "ACTUATORS = [[0.05, 1.0], [0.05, 0.75]]" in env


# -- installed: the package's own tests on the test double -------------------------------------


def _install(packages: list[Path], target: Path) -> dict[str, str]:
    """pip-install ``packages`` into ``target``; the environment that imports them."""
    subprocess.run(
        [sys.executable, "-m", "pip", "install", "-q", "--disable-pip-version-check",
         "--no-index", "--no-deps", "--no-build-isolation", "--target", str(target),
         *map(str, packages)],
        check=True, capture_output=True, text=True, timeout=COMMAND_TIMEOUT,
        env={**os.environ, "PIP_CONFIG_FILE": os.devnull},
    )  # fmt: skip
    drop = ("GYMPRECICE_DISABLE_PLUGINS", "GYMPRECICE_REQUIRE_REAL")
    env = {k: v for k, v in os.environ.items() if k not in drop}
    env["PYTHONPATH"] = str(target)
    return env


def _own_tests(tests: list[Path], env: dict[str, str], cwd: Path, *args: str) -> str:
    proc = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p", "no:randomly",
         "--import-mode=importlib", "--rootdir", str(cwd), *args, *map(str, tests)],
        capture_output=True, text=True, cwd=cwd, env=env, timeout=COMMAND_TIMEOUT,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:]
    return proc.stdout


@pytest.mark.slow
def test_the_default_package_installs_and_passes_check_env_on_the_double(tmp_path, capsys) -> None:
    """Installed with pip, the package registers its id and card on ``import gymprecice``
    and its own tests pass: its case passes ``gymprecice check``, the env passes
    Gymnasium's ``check_env`` on the test double and runs a whole episode. Cost: about
    10 s of CPU (the install, Gymnasium's checker and an episode on the double)."""
    source = tmp_path / "src" / "my-env"
    status, _, err = new(capsys, "my-env", "--dir", str(source))
    assert status == 0, err
    env = _install([source], tmp_path / "site")
    probe = subprocess.run(
        [sys.executable, "-c",
         "from gymprecice.card import find_env; import my_env;"
         "print(find_env('my-env')[0], find_env('my-env/MyEnv-v0')[1].double, my_env.__file__)"],
        capture_output=True, text=True, env=env, cwd=tmp_path, timeout=COMMAND_TIMEOUT,
    )  # fmt: skip
    assert probe.returncode == 0, probe.stderr
    env_id, double, where = probe.stdout.split()
    assert env_id == "my-env/MyEnv-v0" and double == "True"
    assert Path(where).is_relative_to(tmp_path / "site")  # the installed copy
    out = _own_tests([source / "tests"], env, tmp_path)
    assert "4 passed" in out, out


@pytest.mark.slow
def test_every_kind_and_the_solver_plugin_pass_their_own_tests(tmp_path, capsys) -> None:
    """The OpenFOAM, deal.II and FEniCS packages (on the test double their stand-in solver
    replaces the solver) and a package with a solver kind of its own (its plugin through
    gymprecice's conformance suite) pass their own tests, installed together; the whole
    episode each also runs is the default package's test. Cost: about 35 s of CPU (four
    installs, Gymnasium's checker on four doubles)."""
    kinds = [k for k in KNOWN_PLUGIN_KINDS if k in available_kinds()]
    sources = []
    for kind in kinds:
        sources.append(tmp_path / "src" / f"{kind}-env")
        status, _, err = new(capsys, f"{kind}-env", "--kind", kind, "--dir", str(sources[-1]))
        assert status == 0, err
    sources.append(tmp_path / "src" / "own-env")
    status, out, err = new(capsys, "own-env", "--solver-plugin", "--dir", str(sources[-1]))
    assert status == 0, err
    assert "solver: kind own-env" in out
    assert (sources[-1] / "tests/test_conformance.py").is_file()
    env = _install(sources, tmp_path / "site")
    out = _own_tests([s / "tests" for s in sources], env, tmp_path, "-k", "not an_episode")
    assert " failed" not in out and f"{3 * len(sources) + 10} passed" in out, out
