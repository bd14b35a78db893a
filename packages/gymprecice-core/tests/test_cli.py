"""The ``gymprecice`` command line: plugins, check, doctor, and commands from plugins."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from gymprecice import __version__, plugins
from gymprecice.plugin.hookspecs import hookimpl
from gymprecice.plugin.manager import DISABLE_ENV_VAR, PluginWarning, temporary_plugin
from gymprecice.plugin.solver import DoctorCheck
from gymprecice.tools.cli import main


@pytest.fixture(autouse=True)
def fresh(monkeypatch: pytest.MonkeyPatch):
    """Every test sees a freshly loaded manager with core's plugin only (hermetic)."""
    monkeypatch.setattr(plugins, "_manager", None)
    monkeypatch.setenv(DISABLE_ENV_VAR, "1")
    return monkeypatch


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    status = main(list(argv))
    out, err = capsys.readouterr()
    return status, out, err


# -- plugins ------------------------------------------------------------------------------------


def test_plugins_lists_core_plugin(capsys) -> None:
    status, out, _ = run(capsys, "plugins")
    assert status == 0
    assert f"script: gymprecice-core {__version__}" in out
    assert "kinds: command, script" in out
    assert "gymprecice_launch_solver" in out


def test_plugins_json(capsys) -> None:
    class Toy:
        @hookimpl
        def gymprecice_solver_kinds(self):
            return {"toy": "toy solver"}

    with temporary_plugin(Toy(), "toy"):
        status, out, _ = run(capsys, "plugins", "--json")
    assert status == 0
    data = json.loads(out)
    by_name = {p["name"]: p for p in data["plugins"]}
    assert by_name["script"]["distribution"] == "gymprecice-core"
    assert by_name["script"]["version"] == __version__
    assert by_name["script"]["kinds"] == ["command", "script"]
    assert "gymprecice_prepare_case" in by_name["script"]["hooks"]
    assert by_name["toy"]["kinds"] == ["toy"]
    assert by_name["toy"]["hooks"] == ["gymprecice_solver_kinds"]
    assert by_name["toy"]["distribution"] is None
    assert data["failed"] == []


def test_plugins_hook_filter(capsys) -> None:
    class Toy:
        @hookimpl
        def gymprecice_solver_kinds(self):
            return {"toy": "toy solver"}

    with temporary_plugin(Toy(), "toy"):
        _, out, _ = run(capsys, "plugins", "--json", "--hook", "gymprecice_launch_solver")
    assert [p["name"] for p in json.loads(out)["plugins"]] == ["script"]


def test_plugins_shows_failed_plugins(capsys) -> None:
    pm = plugins.get_plugin_manager()
    pm.failures.append(plugins.PluginFailure("broken", "broken-dist", "0.1", "ImportError: x"))
    status, out, _ = run(capsys, "plugins")
    assert status == 0
    assert "broken: broken-dist 0.1  FAILED TO LOAD: ImportError: x" in out


# -- check --------------------------------------------------------------------------------------


def test_check_good_case(capsys, case_dir: Path) -> None:
    status, out, err = run(capsys, "check", str(case_dir))
    assert status == 0, err
    assert out.startswith(f"OK: {case_dir / 'gymprecice-config.json'}")
    assert "participants: Controller (controller), Fluid" in out
    assert "solver fluid: kind command (script) as Fluid" in out
    assert (
        "interface jet1: mesh Controller-Mesh-jet1 (2D) <-> Fluid:Fluid-Mesh-jet1; write Velocity"
        in out
    )
    assert "interface probe: mesh Controller-Mesh-probe (2D)" in out and "read Pressure" in out
    assert "end time: 0.01" in out
    assert "time window size: 0.001" in out
    assert "time windows: 10 (1 per env step)" in out


def test_check_accepts_the_json_file_and_prints_json(capsys, case_dir: Path) -> None:
    status, out, _ = run(capsys, "check", str(case_dir / "gymprecice-config.json"), "--json")
    assert status == 0
    data = json.loads(out)
    assert data["ok"] is True
    assert data["participants"] == ["Controller", "Fluid"]
    assert data["end_time"] == pytest.approx(0.01)
    assert data["time_window_size"] == pytest.approx(0.001)
    assert [i["name"] for i in data["interfaces"]] == ["jet1", "jet2", "probe"]
    assert data["solvers"][0]["plugin"] == "script"


def test_check_unknown_kind_fails_with_installed_kinds(capsys, tmp_path, make_case, base_config):
    config = base_config()
    config["physics_simulation_engine"]["solvers"]["fluid"]["kind"] = "openfoam-typo"
    case = make_case(tmp_path / "case", config)
    status, out, err = run(capsys, "check", str(case))
    assert status == 1
    assert out == ""
    assert "openfoam-typo" in err and "'command'" in err and "'script'" in err


def test_check_shows_the_import_error_of_a_broken_plugin(
    capsys, tmp_path, make_case, base_config, monkeypatch
) -> None:
    from gymprecice import cli
    from gymprecice.plugin.manager import PluginFailure

    broken = PluginFailure("rod", "gymprecice-rod", "0.1", "cannot import 'rod': SyntaxError")
    monkeypatch.setattr(cli, "plugin_failures", lambda: [broken])
    config = base_config()
    config["physics_simulation_engine"]["solvers"]["fluid"]["kind"] = "rod"
    case = make_case(tmp_path / "case", config)
    status, _, err = run(capsys, "check", str(case))
    assert status == 1
    assert "'rod' (from gymprecice-rod 0.1): cannot import 'rod': SyntaxError" in err
    assert "pip install" not in err


def test_check_bad_case_fails(capsys, tmp_path, make_case, base_config) -> None:
    config = base_config(controller={"participant": "Controller", "write_to": {"jet9": "Velocity"}})
    case = make_case(tmp_path / "case", config)
    status, _, err = run(capsys, "check", str(case))
    assert status == 1
    assert err.startswith("FAILED:") and "jet9" in err


def test_check_names_the_solver_as_partner_of_a_mesh_the_controller_maps(
    capsys, case_dir: Path
) -> None:
    """The controller's own read mapping must not make it the probe mesh's partner."""
    status, out, err = run(capsys, "check", str(case_dir))
    assert status == 0, err
    assert "interface probe: mesh Controller-Mesh-probe (2D) <-> Fluid:Fluid-Mesh-probe" in out
    assert "<-> Controller:" not in out


def test_check_refuses_junk_after_the_precice_root_element(capsys, case_dir: Path) -> None:
    xml = case_dir / "precice-config.xml"
    xml.write_text(xml.read_text() + "<oops")
    status, out, err = run(capsys, "check", str(case_dir))
    assert status == 1 and out == ""
    assert f"{xml}:" in err and "junk after document element" in err


def test_check_missing_directory(capsys, tmp_path: Path) -> None:
    status, out, _ = run(capsys, "check", str(tmp_path / "nowhere"), "--json")
    assert status == 1
    data = json.loads(out)
    assert data["ok"] is False and "gymprecice-config.json" in data["error"]


# -- doctor -------------------------------------------------------------------------------------


def _fake_precice(root: Path, body: str) -> Path:
    package = root / "fake-precice" / "precice"
    package.mkdir(parents=True)
    (package / "__init__.py").write_text(body)
    return package.parent


GOOD_PRECICE = """
__version__ = "3.1.1"
def get_version_information():
    return b"3.1.2;no-info [git];Release;Zero"
"""


@pytest.fixture
def bare_path(fresh, tmp_path: Path) -> Path:
    """A PATH with no OpenFOAM, no dpkg, no elasticity."""
    empty = tmp_path / "bin"
    empty.mkdir()
    fresh.setenv("PATH", str(empty))
    fresh.delenv("WM_PROJECT_VERSION", raising=False)
    return empty


def _doctor(capsys) -> tuple[int, dict]:
    status, out, _ = run(capsys, "doctor", "--json")
    return status, json.loads(out)


def _check(report: dict, name: str) -> dict:
    (check,) = [c for c in report["checks"] if c["name"] == name]
    return check


def test_doctor_ok_without_openfoam(capsys, fresh, bare_path, tmp_path) -> None:
    fresh.setenv("PYTHONPATH", str(_fake_precice(tmp_path, GOOD_PRECICE)))
    fresh.setenv("GYMPRECICE_STACK_PREFIX", str(tmp_path / "stack"))
    status, report = _doctor(capsys)
    assert status == 0 and report["ok"] is True
    precice = _check(report, "pyprecice")
    assert precice["ok"] and precice["required"]
    assert "pyprecice 3.1.1" in precice["detail"] and "preCICE library 3.1.2" in precice["detail"]
    assert _check(report, "python")["ok"] is True
    # core names no solver: OpenFOAM, deal.II and elasticity are their plugins' checks
    names = {c["name"] for c in report["checks"]}
    assert not names & {"OpenFOAM", "deal.II", "elasticity"}
    # the stack core can build: what is missing and the command that builds it
    stack = _check(report, "stack: precice")
    assert stack["ok"] is False and stack["advice"] == "run `gymprecice install precice`"
    assert stack["source"] == "install" and stack["required"] is False


def test_doctor_fails_without_pyprecice(capsys, fresh, bare_path, tmp_path) -> None:
    broken = "raise ImportError('libprecice.so.3: cannot open shared object file')\n"
    fresh.setenv("PYTHONPATH", str(_fake_precice(tmp_path, broken)))
    status, report = _doctor(capsys)
    assert status == 1 and report["ok"] is False
    precice = _check(report, "pyprecice")
    assert precice["ok"] is False and "libprecice.so.3" in precice["detail"]
    assert "does not find libprecice" in precice["advice"]
    assert "gymprecice install pyprecice --force" in precice["advice"]


def test_doctor_survives_an_import_that_kills_the_interpreter(capsys, fresh, tmp_path) -> None:
    crash = "import os\nos.write(2, b'MPI_Init failed\\n')\nos.abort()\n"
    fresh.setenv("PYTHONPATH", str(_fake_precice(tmp_path, crash)))
    status, report = _doctor(capsys)
    assert status == 1
    assert "crashed" in _check(report, "pyprecice")["detail"]
    assert "MPI_Init failed" in _check(report, "pyprecice")["detail"]


def test_doctor_rejects_precice_v2(capsys, fresh, tmp_path) -> None:
    v2 = '__version__ = "2.5.0"\ndef get_version_information():\n    return "2.5.0;Release"\n'
    fresh.setenv("PYTHONPATH", str(_fake_precice(tmp_path, v2)))
    status, report = _doctor(capsys)
    assert status == 1
    assert "needs preCICE v3" in _check(report, "pyprecice")["advice"]


def test_doctor_includes_plugin_checks(capsys, fresh, bare_path, tmp_path) -> None:
    fresh.setenv("PYTHONPATH", str(_fake_precice(tmp_path, GOOD_PRECICE)))

    class Needs:
        @hookimpl
        def gymprecice_doctor_checks(self):
            return [DoctorCheck("toy-adapter", ok=False, advice="build it", required=True)]

    class Broken:
        @hookimpl
        def gymprecice_doctor_checks(self):
            raise RuntimeError("probe failed")

    class Wrong:
        @hookimpl
        def gymprecice_doctor_checks(self):
            return ["not a check"]

    with (
        temporary_plugin(Needs(), "needs"),
        temporary_plugin(Broken(), "broken"),
        temporary_plugin(Wrong(), "wrong"),
    ):
        status, report = _doctor(capsys)
    assert status == 1  # a plugin's required check failed
    by_source = {c["source"]: c for c in report["checks"] if c["source"] != "core"}
    assert by_source["needs"]["name"] == "toy-adapter" and by_source["needs"]["required"]
    assert "probe failed" in by_source["broken"]["detail"]
    assert "not a check" in by_source["wrong"]["detail"]
    assert by_source["script"]["name"] == "bash"


def test_doctor_text_output(capsys, fresh, bare_path, tmp_path) -> None:
    fresh.setenv("PYTHONPATH", str(_fake_precice(tmp_path, GOOD_PRECICE)))
    status, out, _ = run(capsys, "doctor")
    assert status == 0
    assert "[ok]      pyprecice (required)" in out
    assert "stack: precice [install]" in out
    assert out.rstrip().endswith("Everything required is there.")


# -- plugin commands, usage ---------------------------------------------------------------------


class HelloCommands:
    @hookimpl
    def gymprecice_register_commands(self, subparsers):
        parser = subparsers.add_parser("hello", help="say hello")
        parser.add_argument("--name", default="world")
        parser.set_defaults(func=self.hello)

    @staticmethod
    def hello(args):
        print(f"hello {args.name}")
        return 3


def test_plugin_contributed_command(capsys) -> None:
    with temporary_plugin(HelloCommands(), "hello"):
        status, out, _ = run(capsys, "hello", "--name", "flow")
        assert (status, out) == (3, "hello flow\n")
        with pytest.raises(SystemExit):
            main(["--help"])
        assert "say hello" in capsys.readouterr().out
    with pytest.raises(SystemExit):  # gone with its plugin
        main(["hello"])


def test_plugin_cannot_break_or_replace_built_in_commands(capsys, fresh, tmp_path) -> None:
    class Clash:
        @hookimpl
        def gymprecice_register_commands(self, subparsers):
            subparsers.add_parser("check").set_defaults(func=lambda args: 99)

    class Broken:
        @hookimpl
        def gymprecice_register_commands(self, subparsers):
            raise RuntimeError("bad command plugin")

    with (
        temporary_plugin(Clash(), "clash"),
        temporary_plugin(Broken(), "broken"),
        pytest.warns(PluginWarning) as record,
    ):
        status, _, _ = run(capsys, "check", str(tmp_path / "nowhere"))
    assert status == 1  # the built-in check ran, not the plugin's
    messages = " ".join(str(w.message) for w in record)
    assert "'clash'" in messages and "bad command plugin" in messages


def test_no_command_prints_usage(capsys) -> None:
    status, _, err = run(capsys)
    assert status == 2 and "usage: gymprecice" in err


def test_python_dash_m_gymprecice() -> None:
    env = dict(os.environ, **{DISABLE_ENV_VAR: "1"})
    proc = subprocess.run(
        [sys.executable, "-m", "gymprecice", "--version"],
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == f"gymprecice {__version__}"
