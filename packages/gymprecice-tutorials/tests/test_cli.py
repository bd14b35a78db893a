"""The tutorials' sub-commands of ``gymprecice``: parsing, solver requirements, errors."""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

import pytest

from gymprecice.cli import build_parser, main
from gymprecice_tutorials import manifest, train
from gymprecice_tutorials.environments import ENVIRONMENTS, find_environment

COMMANDS = ("train", "evaluate", "baseline", "open-loop", "plot")


def _check(name: str, ok: bool, required: bool = False, source: str = "core") -> dict:
    return {
        "name": name,
        "ok": ok,
        "required": required,
        "source": source,
        "detail": "d",
        "advice": "a",
    }


def test_commands_are_added_to_gymprecice():
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    assert set(COMMANDS) <= set(sub.choices)
    args = parser.parse_args(["train", "jet-cylinder"])
    assert (args.n_envs, args.timesteps, args.n_steps, args.seed) == (1, 100_000, 80, 0)
    assert args.require_solvers is False and args.double is False
    args = parser.parse_args(["evaluate", "jet-cylinder"])
    assert args.default_episode_time == 10.0 and args.episode_time is None


def test_env_names_and_ids_resolve():
    assert find_environment("jet-cylinder").env_id == "gymprecice/JetCylinder-v0"
    assert find_environment("gymprecice/RotatingCylinder-v0").name == "rotating-cylinder"
    assert find_environment("Quickstart-v0").name == "quickstart"
    with pytest.raises(KeyError, match="jet-cylinder"):
        find_environment("cylinder")


def test_unknown_environment_is_a_usage_error(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["train", "no-such-env"]) == 2
    assert "choose one of jet-cylinder" in capsys.readouterr().err


def test_bad_env_kwargs_are_refused_by_the_parser(capsys):
    with pytest.raises(SystemExit) as exit_info:
        build_parser().parse_args(["baseline", "quickstart", "--env-kwargs", "[1, 2]"])
    assert exit_info.value.code == 2
    assert "JSON object" in capsys.readouterr().err


def test_double_needs_a_scripted_flow(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit, match="no scripted fake flow"):
        main(["baseline", "perpendicular-flap", "--double"])
    with pytest.raises(SystemExit, match=r"max-time in your precice-config\.xml"):
        main(["baseline", "quickstart", "--case", str(tmp_path), "--episode-time", "1"])


# -- --require-solvers -----------------------------------------------------------------------


def test_missing_requirements_depend_on_the_environment():
    report = {
        "ok": True,
        "checks": [
            _check("python", True, required=True),
            _check("pyprecice", True, required=True),
            _check("OpenFOAM", True),
            _check("mpirun", False, source="openfoam"),
            _check("gmsh", False, source="openfoam"),
            _check("elasticity", False),
            _check("deal.II-preCICE adapter (elasticity)", False, source="dealii"),
        ],
    }
    names = {
        env: [c["name"] for c in train.missing_requirements(report, ENVIRONMENTS[env])]
        for env in ENVIRONMENTS
    }
    assert names["jet-cylinder"] == ["mpirun"]  # two processes; gmsh and deal.II unused
    assert names["quickstart"] == []  # one process
    assert names["perpendicular-flap"] == ["elasticity", "deal.II-preCICE adapter (elasticity)"]
    report["checks"].append(_check("OpenFOAM-preCICE adapter", False, source="openfoam"))
    report["checks"][1]["ok"] = False
    for env in ENVIRONMENTS:
        missing = [c["name"] for c in train.missing_requirements(report, ENVIRONMENTS[env])]
        assert "pyprecice" in missing and "OpenFOAM-preCICE adapter" in missing


def test_require_solvers_passes_when_the_doctor_finds_everything(monkeypatch, capsys):
    report = {"ok": True, "checks": [_check("pyprecice", True, required=True)]}
    monkeypatch.setattr("gymprecice.cli.doctor_report", lambda: report)
    assert train.require_solvers(ENVIRONMENTS["jet-cylinder"]) == 0
    assert capsys.readouterr().err == ""


def test_require_solvers_explains_a_missing_precice(tmp_path, monkeypatch, capsys):
    from gymprecice.cli import PRECICE_ADVICE

    report = {
        "ok": False,
        "checks": [
            _check("python", True, required=True),
            {
                **_check("pyprecice", False, required=True),
                "detail": "ModuleNotFoundError: No module named 'precice'",
                "advice": PRECICE_ADVICE,
            },
            _check("OpenFOAM", True),
        ],
    }
    monkeypatch.setattr("gymprecice.cli.doctor_report", lambda: report)
    monkeypatch.chdir(tmp_path)
    assert main(["train", "jet-cylinder", "--require-solvers"]) == 1
    err = capsys.readouterr().err
    assert "jet-cylinder cannot run on real solvers" in err
    assert "missing: pyprecice (the preCICE library and its Python bindings)" in err
    assert "[MISSING] pyprecice (required): ModuleNotFoundError" in err
    assert "build preCICE v3" in err  # the doctor's advice
    assert "--double" in err
    assert list(tmp_path.iterdir()) == []  # nothing was started or written


def test_train_require_solvers_on_this_machine(tmp_path):
    """The real doctor: stop at once, naming what this machine lacks (preCICE, adapter)."""
    from gymprecice.cli import doctor_report

    missing = train.missing_requirements(doctor_report(), ENVIRONMENTS["jet-cylinder"])
    if not missing:
        pytest.skip("this machine has everything the jet cylinder needs")
    started = time.monotonic()
    proc = subprocess.run(
        [sys.executable, "-m", "gymprecice", "train", "jet-cylinder", "--require-solvers"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 1, proc.stderr
    assert time.monotonic() - started < 60
    assert "jet-cylinder cannot run on real solvers" in proc.stderr
    for check in missing:
        assert f"[MISSING] {check['name']}" in proc.stderr or f"[--]      {check['name']}" in (
            proc.stderr
        )
    if any(c["name"] == "pyprecice" for c in missing):
        assert "preCICE" in proc.stderr
    assert list(tmp_path.iterdir()) == []


# -- manifest --------------------------------------------------------------------------------


def test_manifest_hashes_configuration_not_results(tmp_path):
    case = tmp_path / "case"
    (case / "fluid" / "system").mkdir(parents=True)
    (case / "fluid" / "constant" / "polyMesh").mkdir(parents=True)
    (case / "fluid" / "postProcessing" / "probes" / "0").mkdir(parents=True)
    (case / "gymprecice-config.json").write_text("{}")
    (case / "fluid" / "system" / "controlDict").write_text("application pimpleFoam;")
    (case / "fluid" / "constant" / "polyMesh" / "points").write_text("(0 0 0)")
    (case / "fluid" / "postProcessing" / "probes" / "0" / "p").write_text("1 2")
    (case / "fluid" / "0.5").mkdir()
    (case / "fluid" / "0.5" / "U").write_text("field")
    hashes = manifest.config_file_hashes(case)
    assert sorted(hashes) == ["fluid/system/controlDict", "gymprecice-config.json"]
    path = manifest.write_manifest(
        tmp_path / "out",
        command="baseline",
        argv=["gymprecice", "baseline", "x"],
        case_dir=case,
        seeds={"seed": 3},
        settings={"path": tmp_path, "n": 2},
        solvers={"ok": False, "checks": []},
    )
    data = json.loads(path.read_text())
    assert data["command_line"] == "gymprecice baseline x"
    assert data["settings"] == {"path": str(tmp_path), "n": 2}
    assert data["config_files"] == hashes and data["seeds"] == {"seed": 3}
    assert data["packages"]["gymprecice-tutorials"] is not None
    assert data["packages"]["pyprecice"] is None or isinstance(data["packages"]["pyprecice"], str)
    assert manifest.read_manifest(tmp_path / "out") == data
    assert not list(Path(tmp_path / "out").glob("*.tmp"))
