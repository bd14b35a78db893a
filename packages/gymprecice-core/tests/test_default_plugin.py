"""Core's default plugin: kinds "script" (the paper's scripts) and "command" (an argv)."""

from __future__ import annotations

import os
import stat
import sys
from pathlib import Path

import numpy as np
import pytest

from gymprecice import default_plugin
from gymprecice.env.processes import run_to_completion
from gymprecice.plugin.errors import CaseError, ConfigError, SolverCrashedError, SolverTimeoutError
from gymprecice.plugin.solver import LaunchSpec, SolverContext
from gymprecice.testing.conformance import SolverPluginConformance, make_solver_context

PRERUN = """#!/bin/sh
echo prerun >> prerun.count
"""
RESET = """#!/bin/sh
echo "$GYMPRECICE_SEED $GYMPRECICE_SOLVER $GYMPRECICE_ENV_INDEX" >> reset.count
"""
RUN = """#!/bin/sh
echo "running in $(pwd)" > run.out
"""


def _script(path: Path, text: str, *, executable: bool = True) -> Path:
    path.write_text(text)
    mode = path.stat().st_mode
    path.chmod(mode | stat.S_IXUSR if executable else mode & ~0o111)
    return path


def _script_case(root: Path) -> Path:
    source = root / "case" / "fluid"
    source.mkdir(parents=True)
    _script(source / "prerun.sh", PRERUN)
    _script(source / "reset.sh", RESET)
    _script(source / "run.sh", RUN)
    (source / "input.txt").write_text("pristine\n")
    return source


SCRIPT_OPTIONS = {"prerun_script": "prerun.sh", "reset_script": "reset.sh", "run_script": "run.sh"}


def _script_solver(base: Path, **options) -> SolverContext:
    opts = {**SCRIPT_OPTIONS, **options}
    return make_solver_context("script", _script_case(base), base, name="fluid", options=opts)


def _command_solver(base: Path, **options) -> SolverContext:
    source = base / "case" / "partner"
    source.mkdir(parents=True)
    (source / "input.txt").write_text("pristine\n")
    opts = {
        "argv": ["{python}", "-c", "open('ran.txt', 'w').write('ok')"],
        "prepare_argv": ["{python}", "-c", "open('prepared.txt', 'a').write('p')"],
        "reset_argv": ["{python}", "-c", "open('reset.txt', 'a').write('r')"],
        **options,
    }
    return make_solver_context(
        "command", source, base, name="partner", options=opts, participant="Fluid"
    )


# -- the conformance suite, run for both kinds ---------------------------------------------


class TestScriptKindConformance(SolverPluginConformance):
    @pytest.fixture
    def plugin(self):
        return default_plugin

    @pytest.fixture
    def kind(self):
        return "script"

    @pytest.fixture
    def make_solver(self):
        return _script_solver


class TestCommandKindConformance(SolverPluginConformance):
    @pytest.fixture
    def plugin(self):
        return default_plugin

    @pytest.fixture
    def kind(self):
        return "command"

    @pytest.fixture
    def make_solver(self):
        return _command_solver


# -- kind "script" ----------------------------------------------------------------------------


def test_prerun_once_reset_every_episode_run_launched(tmp_path: Path) -> None:
    solver = _script_solver(tmp_path)
    assert default_plugin.gymprecice_prepare_case(solver) is True
    for seed in (1, 2, 3):
        solver.rng = np.random.default_rng(seed)
        assert default_plugin.gymprecice_reset_case(solver) is True
    assert (solver.run_dir / "prerun.count").read_text().splitlines() == ["prerun"]
    resets = (solver.run_dir / "reset.count").read_text().splitlines()
    assert len(resets) == 3
    # the seed comes from the episode's generator: reproducible, different per episode
    seeds = [line.split()[0] for line in resets]
    expected = [str(int(np.random.default_rng(s).integers(2**31 - 1))) for s in (1, 2, 3)]
    assert seeds == expected
    assert all(line.split()[1:] == ["fluid", "0"] for line in resets)
    assert (solver.run_dir / "prerun.log").exists() and (solver.run_dir / "reset.log").exists()

    spec = default_plugin.gymprecice_launch_solver(solver)
    assert isinstance(spec, LaunchSpec)
    assert spec.argv == [str(solver.run_dir / "run.sh")]
    assert spec.cwd == solver.run_dir
    assert spec.env["GYMPRECICE_SOLVER"] == "fluid"
    run_to_completion("fluid", spec, timeout=30)
    assert (solver.run_dir / "run.out").read_text().strip() == f"running in {solver.run_dir}"
    assert not (solver.source_dir / "run.out").exists()


def test_reset_and_prerun_are_optional(tmp_path: Path) -> None:
    solver = _script_solver(tmp_path)
    solver.options = {"run_script": "run.sh"}
    assert default_plugin.gymprecice_prepare_case(solver) is True
    assert default_plugin.gymprecice_reset_case(solver) is True
    assert not (solver.run_dir / "prerun.count").exists()
    assert not (solver.run_dir / "reset.count").exists()


def test_missing_script_names_the_file_and_the_fix(tmp_path: Path) -> None:
    solver = _script_solver(tmp_path, reset_script="reset-typo.sh")
    with pytest.raises(CaseError) as info:
        default_plugin.gymprecice_prepare_case(solver)
    message = str(info.value)
    assert "reset-typo.sh" in message and str(solver.source_dir) in message
    assert "physics_simulation_engine.reset_script" in message
    # checked before the prerun: nothing ran
    assert not (solver.run_dir / "prerun.count").exists()


def test_missing_run_script_option_is_a_config_error(tmp_path: Path) -> None:
    solver = _script_solver(tmp_path)
    solver.options = {"reset_script": "reset.sh"}
    with pytest.raises(ConfigError, match="run_script"):
        default_plugin.gymprecice_prepare_case(solver)


def test_non_executable_script_says_chmod(tmp_path: Path) -> None:
    solver = _script_solver(tmp_path)
    _script(solver.run_dir / "run.sh", RUN, executable=False)
    with pytest.raises(CaseError) as info:
        default_plugin.gymprecice_launch_solver(solver)
    assert f"chmod +x {solver.source_dir / 'run.sh'}" in str(info.value)


def test_interpreter_option_runs_non_executable_scripts(tmp_path: Path) -> None:
    solver = _script_solver(tmp_path, interpreter="bash")
    _script(solver.run_dir / "prerun.sh", PRERUN, executable=False)
    assert default_plugin.gymprecice_prepare_case(solver) is True
    assert (solver.run_dir / "prerun.count").read_text() == "prerun\n"
    spec = default_plugin.gymprecice_launch_solver(solver)
    assert spec.argv == ["bash", str(solver.run_dir / "run.sh")]


def test_script_without_shebang_runs_under_sh(tmp_path: Path) -> None:
    solver = _script_solver(tmp_path)
    _script(solver.run_dir / "run.sh", "echo plain > plain.out\n")
    spec = default_plugin.gymprecice_launch_solver(solver)
    assert spec.argv == ["sh", str(solver.run_dir / "run.sh")]
    run_to_completion("fluid", spec, timeout=30)
    assert (solver.run_dir / "plain.out").read_text() == "plain\n"


def test_windows_line_endings_are_reported(tmp_path: Path) -> None:
    solver = _script_solver(tmp_path)
    _script(solver.run_dir / "run.sh", "#!/bin/sh\r\necho hi\r\n")
    with pytest.raises(CaseError, match="dos2unix"):
        default_plugin.gymprecice_launch_solver(solver)


def test_failing_prerun_raises_with_the_log(tmp_path: Path) -> None:
    solver = _script_solver(tmp_path)
    _script(solver.run_dir / "prerun.sh", "#!/bin/sh\necho 'mesh generation failed'\nexit 3\n")
    with pytest.raises(SolverCrashedError) as info:
        default_plugin.gymprecice_prepare_case(solver)
    assert info.value.returncode == 3
    assert "mesh generation failed" in str(info.value)


def test_reset_timeout_option(tmp_path: Path) -> None:
    solver = _script_solver(tmp_path, reset_timeout=0.5)
    _script(solver.run_dir / "reset.sh", "#!/bin/sh\nsleep 30\n")
    with pytest.raises(SolverTimeoutError):
        default_plugin.gymprecice_reset_case(solver)


@pytest.mark.parametrize("bad", [0, -1, "soon"])
def test_bad_timeout_is_a_config_error(tmp_path: Path, bad) -> None:
    solver = _script_solver(tmp_path, reset_timeout=bad)
    with pytest.raises(ConfigError, match="reset_timeout"):
        default_plugin.gymprecice_reset_case(solver)


# -- kind "command" ---------------------------------------------------------------------------


def test_command_placeholders_and_steps(tmp_path: Path) -> None:
    solver = _command_solver(
        tmp_path,
        argv=[
            "{python}",
            "-m",
            "gymprecice.testing.partner",
            "--participant",
            "{participant}",
            "--config",
            "{precice_config}",
            '{"json": {"braces": "kept"}}',
            "{run_dir}/{solver}-{env_index}",
        ],
    )
    solver.precice_config_file = tmp_path / "env_0" / "precice-config.xml"
    assert default_plugin.gymprecice_prepare_case(solver) is True
    assert default_plugin.gymprecice_reset_case(solver) is True
    assert default_plugin.gymprecice_reset_case(solver) is True
    assert (solver.run_dir / "prepared.txt").read_text() == "p"
    assert (solver.run_dir / "reset.txt").read_text() == "rr"
    spec = default_plugin.gymprecice_launch_solver(solver)
    assert list(spec.argv) == [
        sys.executable,
        "-m",
        "gymprecice.testing.partner",
        "--participant",
        "Fluid",
        "--config",
        str(solver.precice_config_file),
        '{"json": {"braces": "kept"}}',
        f"{solver.run_dir}/partner-0",
    ]
    assert spec.cwd == solver.run_dir
    assert spec.env["GYMPRECICE_PRECICE_CONFIG"] == str(solver.precice_config_file)


def test_command_string_is_split_like_a_shell(tmp_path: Path) -> None:
    solver = _command_solver(tmp_path, argv="{python} -c 'print(1)'")
    spec = default_plugin.gymprecice_launch_solver(solver)
    assert list(spec.argv) == [sys.executable, "-c", "print(1)"]


def test_command_env_and_log_name(tmp_path: Path) -> None:
    solver = _command_solver(tmp_path, env={"OMP_NUM_THREADS": 1}, log_name="partner.log")
    spec = default_plugin.gymprecice_launch_solver(solver)
    assert spec.env["OMP_NUM_THREADS"] == "1"
    assert spec.log_name == "partner.log"


def test_command_without_argv_is_a_config_error(tmp_path: Path) -> None:
    solver = _command_solver(tmp_path)
    del solver.options["argv"]
    with pytest.raises(ConfigError, match=r"options\.argv"):
        default_plugin.gymprecice_prepare_case(solver)


@pytest.mark.parametrize("argv", [[["nested"]], {"a": 1}, [None]])
def test_command_argv_must_be_strings(tmp_path: Path, argv) -> None:
    solver = _command_solver(tmp_path, argv=argv)
    with pytest.raises(ConfigError, match="list of"):
        default_plugin.gymprecice_launch_solver(solver)


def test_unknown_program_is_reported_at_prepare(tmp_path: Path) -> None:
    solver = _command_solver(tmp_path, reset_argv=["no-such-program-gymprecice", "x"])
    with pytest.raises(CaseError, match="no-such-program-gymprecice"):
        default_plugin.gymprecice_prepare_case(solver)
    assert not (solver.run_dir / "prepared.txt").exists()


def test_relative_program_is_looked_up_in_run_dir(tmp_path: Path) -> None:
    solver = _command_solver(tmp_path, argv=["./solve", "--fast"])
    with pytest.raises(CaseError, match="solve"):
        default_plugin.gymprecice_launch_solver(solver)
    _script(solver.run_dir / "solve", "#!/bin/sh\n")
    assert list(default_plugin.gymprecice_launch_solver(solver).argv) == ["./solve", "--fast"]


# -- the other hooks --------------------------------------------------------------------------


def test_declares_both_kinds() -> None:
    assert set(default_plugin.gymprecice_solver_kinds()) == {"script", "command"}


def test_foreign_kinds_are_left_alone(tmp_path: Path) -> None:
    solver = _script_solver(tmp_path)
    solver.kind = "openfoam"
    assert default_plugin.gymprecice_prepare_case(solver) is None
    assert default_plugin.gymprecice_reset_case(solver) is None
    assert default_plugin.gymprecice_launch_solver(solver) is None
    assert default_plugin.gymprecice_check_solver(solver, "bash: foo: command not found") is None
    assert not (solver.run_dir / "prerun.count").exists()


def test_check_solver_explains_shell_failures(tmp_path: Path) -> None:
    solver = _script_solver(tmp_path)
    assert default_plugin.gymprecice_check_solver(solver, "Time = 0.1\nTime = 0.2\n") is None
    message = default_plugin.gymprecice_check_solver(
        solver, "starting\n./run.sh: line 3: pimpleFoam: command not found\n"
    )
    assert message is not None
    assert "pimpleFoam: command not found" in message and "not on PATH" in message


def test_doctor_reports_bash(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setenv("PATH", str(tmp_path))
    (check,) = default_plugin.gymprecice_doctor_checks()
    assert check.name == "bash" and check.ok is False and "install bash" in check.advice
    monkeypatch.setenv("PATH", os.defpath)
    (check,) = default_plugin.gymprecice_doctor_checks()
    assert check.ok is True


def test_non_executable_command_file_says_chmod(tmp_path: Path) -> None:
    """An existing file without the x bit is not 'missing': say how to fix it."""
    solver = _command_solver(tmp_path, argv=["./solve.sh"])
    for where in (solver.source_dir, solver.run_dir):
        _script(where / "solve.sh", "#!/bin/sh\n", executable=False)
    with pytest.raises(CaseError) as info:
        default_plugin.gymprecice_launch_solver(solver)
    assert f"chmod +x {solver.source_dir / 'solve.sh'}" in str(info.value)
    assert "not executable" in str(info.value)


@pytest.mark.parametrize(
    ("kind", "typo", "meant"),
    [("command", "log_nme", "log_name"), ("script", "reset_timout", "reset_timeout")],
)
def test_misspelled_option_is_refused_with_the_closest_key(
    tmp_path: Path, kind: str, typo: str, meant: str
) -> None:
    make = _command_solver if kind == "command" else _script_solver
    solver = make(tmp_path, **{typo: 5})
    solver.config_file = tmp_path / "gymprecice-config.json"
    (problem,) = default_plugin.gymprecice_validate_case(solver)
    assert str(solver.config_file) in problem
    assert f"{typo!r} (did you mean {meant!r}?)" in problem
    assert f"solvers.{solver.name}.options" in problem
    with pytest.raises(ConfigError, match=typo):
        default_plugin.gymprecice_prepare_case(solver)


def test_known_options_pass_validation(tmp_path: Path) -> None:
    solver = _command_solver(tmp_path, log_name="x.log", reset_timeout=5, outputs="openfoam")
    assert default_plugin.gymprecice_validate_case(solver) == []
    other = make_solver_context("openfoam", solver.source_dir, tmp_path, options={"np": 2})
    assert default_plugin.gymprecice_validate_case(other) is None


# -- check catches what launching would refuse ----------------------------------------------


@pytest.fixture
def broken_case(tmp_path, make_case, base_config):
    """``broken_case(kind, options)``: the default test case with solver fluid's kind/options."""

    def make(kind: str, options: dict) -> Path:
        config = base_config()
        config["physics_simulation_engine"]["solvers"]["fluid"].update(kind=kind, options=options)
        return make_case(tmp_path / "case", config)

    return make


@pytest.mark.parametrize(
    ("kind", "options", "prepare", "shown"),
    [
        ("script", {"run_script": "run.sh"}, None, "the run script 'run.sh' does not exist"),
        ("script", {"run_script": "run.sh"}, "run.sh:644", "is not executable; run `chmod +x"),
        ("command", {"argv": ["./solve"]}, None, "'./solve', which is not an executable file"),
        ("command", {"argv": ["./solve"]}, "solve:644", "is not executable; run `chmod +x"),
        ("command", {"argv": ["no-such-program-x"]}, None, "not an executable program on PATH"),
        ("command", {"argv": ["python3", "solver.py"]}, None, "runs python3 on this script"),
        ("command", {"argv": ["{python}", "solver.py", "-v"]}, None, "on this script"),
    ],
)
def test_check_refuses_what_reset_would_with_the_same_message(
    broken_case, capsys, kind, options, prepare, shown
):
    from gymprecice.env.config import load_config
    from gymprecice.tools.cli import main

    case = broken_case(kind, options)
    if prepare:
        name, mode = prepare.split(":")
        (case / "fluid" / name).write_text("#!/bin/sh\n")
        (case / "fluid" / name).chmod(int(mode, 8))
    assert main(["check", str(case)]) == 1
    reported = capsys.readouterr().err
    assert shown in reported
    # reset() (through the launch hook on the env's copy) says the same
    config = load_config(case, validate_cases=False)
    spec = config.solvers["fluid"]
    solver = SolverContext(
        name="fluid",
        kind=kind,
        run_dir=case / "fluid",
        source_dir=case / "fluid",
        env_dir=case,
        participant="Fluid",
        options=dict(spec.options),
        config_file=config.file,
    )
    with pytest.raises((CaseError, ConfigError)) as raised:
        default_plugin.gymprecice_launch_solver(solver=solver)
    assert str(raised.value) in reported


def test_check_accepts_a_case_that_launches(broken_case, capsys):
    from gymprecice.tools.cli import main

    case = broken_case("command", {"argv": ["{python}", "solver.py"]})
    (case / "fluid" / "solver.py").write_text("print('hi')\n")
    assert main(["check", str(case)]) == 0, capsys.readouterr().err


# -- outputs: any participant's watch point ---------------------------------------------------


def _solid(base: Path, kind: str = "command", **fields) -> SolverContext:
    """A solver playing the fake flap's Solid, whose precice-config.xml declares Flap-Tip."""
    from gymprecice.testing import case_config

    source = base / "case" / "solid"
    source.mkdir(parents=True)
    xml = case_config("fake_flap", base / "xml", variant="compositional")
    fields.setdefault("participant", "Solid")
    return make_solver_context(kind, source, base, name="solid", precice_config=xml, **fields)


@pytest.mark.parametrize("kind", ["command", "script", "openfoam", "dealii"])
def test_core_opens_a_participants_watch_point_whatever_its_kind(tmp_path: Path, kind) -> None:
    """Issue 40, bug 1: preCICE writes the log, so no solver plugin is needed to read it."""
    from gymprecice.plugin.manager import get_plugin_manager
    from gymprecice.plugin.watchpoints import WatchPointLog

    solver = _solid(tmp_path, kind)
    reader = get_plugin_manager().hook.gymprecice_open_output(
        solver=solver, name="watchpoint", options={"point": "Flap-Tip"}
    )
    assert isinstance(reader, WatchPointLog)
    assert reader.path == solver.run_dir / "precice-Solid-watchpoint-Flap-Tip.log"


def test_an_undeclared_watch_point_names_the_xml_and_the_tag_to_add(tmp_path: Path) -> None:
    solver = _solid(tmp_path)
    with pytest.raises(ConfigError, match=r"precice-config.xml: participant 'Solid' has no "):
        default_plugin.gymprecice_open_output(solver, "watchpoint", {"point": "Tip"})
    with pytest.raises(ConfigError, match=r"no participant 'Rod'.*\['Controller', 'Fluid'"):
        default_plugin.gymprecice_open_output(
            solver, "watchpoint", {"point": "Flap-Tip", "participant": "Rod"}
        )
    with pytest.raises(ConfigError, match=r"needs the watch point's name"):
        default_plugin.gymprecice_open_output(solver, "watchpoint", {"pont": "Flap-Tip"})


def test_core_steps_aside_where_a_plugin_knows_better(tmp_path: Path) -> None:
    # a plugin's solver whose participant only its own files name (deal.II's parameters.prm)
    nameless = _solid(tmp_path / "a", "dealii", participant=None)
    assert (
        default_plugin.gymprecice_open_output(nameless, "watchpoint", {"point": "Flap-Tip"}) is None
    )
    # ...but core's own kinds have no such files: the fix is named
    with pytest.raises(ConfigError, match=r"whose watch point 'Flap-Tip'\? Set the solver's"):
        default_plugin.gymprecice_open_output(
            _solid(tmp_path / "b", participant=None), "watchpoint", {"point": "Flap-Tip"}
        )
    # a stand-in that writes an undeclared log itself is read by the plugin it names
    stand_in = _solid(tmp_path / "c", options={"outputs": "dealii"})
    assert default_plugin.gymprecice_open_output(stand_in, "watchpoint", {"point": "Tip"}) is None
    # every other output is the plugins'
    assert default_plugin.gymprecice_open_output(stand_in, "probes", {}) is None
