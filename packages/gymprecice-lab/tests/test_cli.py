"""The lab's sub-commands of ``gymprecice`` on the tutorials' envs: parsing, solver
requirements, errors."""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

import pytest

from gymprecice.tools.cli import build_parser, main
from gymprecice_lab import hyperparams, manifest, requirements
from gymprecice_lab.cli.settings import from_argv
from gymprecice_lab.common.constructor_kwargs import build_env_kwargs
from gymprecice_lab.common.registered_env import LabEnvError, find_lab_env, lab_envs

ENVIRONMENTS = {env.name: env for env in lab_envs()}

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
    assert (args.n_envs, args.timesteps, args.seed, args.algo) == (1, 100_000, 0, "ppo")
    assert args.n_steps is None  # the algorithm's default, unless typed
    assert args.require_solvers is False and args.double is False
    args = parser.parse_args(["evaluate", "jet-cylinder"])
    assert args.rollout is True and args.episode_time is None


def test_env_names_and_ids_resolve():
    assert find_lab_env("jet-cylinder").env_id == "gymprecice/JetCylinder-v0"
    assert find_lab_env("gymprecice/RotatingCylinder-v0").name == "rotating-cylinder"
    assert find_lab_env("Quickstart-v0").name == "quickstart"
    with pytest.raises(LabEnvError, match="jet-cylinder"):
        find_lab_env("cylinder")


def test_unknown_environment_is_a_usage_error(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["train", "no-such-env"]) == 2
    assert "installed packages register: jet-cylinder (gymprecice/JetCylinder-v0)" in (
        capsys.readouterr().err
    )


def test_bad_env_kwargs_are_refused_by_the_parser(capsys):
    with pytest.raises(SystemExit) as exit_info:
        build_parser().parse_args(["baseline", "quickstart", "--env-kwargs", "[1, 2]"])
    assert exit_info.value.code == 2
    assert "JSON object" in capsys.readouterr().err


def test_double_needs_a_scripted_flow(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit, match="lab card field 'double'") as refused:
        main(["baseline", "perpendicular-flap", "--double"])
    assert refused.value.code == 2 and not (tmp_path / "runs").exists()
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
        env: [c["name"] for c in requirements.missing_requirements(report, ENVIRONMENTS[env])]
        for env in ENVIRONMENTS
    }
    assert names["jet-cylinder"] == ["mpirun"]  # two processes; gmsh and deal.II unused
    assert names["quickstart"] == []  # one process
    assert names["perpendicular-flap"] == ["elasticity", "deal.II-preCICE adapter (elasticity)"]
    report["checks"].append(_check("OpenFOAM-preCICE adapter", False, source="openfoam"))
    report["checks"][1]["ok"] = False
    for env in ENVIRONMENTS:
        missing = [c["name"] for c in requirements.missing_requirements(report, ENVIRONMENTS[env])]
        assert "pyprecice" in missing and "OpenFOAM-preCICE adapter" in missing


def test_require_solvers_passes_when_the_doctor_finds_everything(monkeypatch, capsys):
    report = {"ok": True, "checks": [_check("pyprecice", True, required=True)]}
    monkeypatch.setattr("gymprecice.cli.doctor_report", lambda: report)
    assert requirements.require_solvers(ENVIRONMENTS["jet-cylinder"]) == 0
    assert capsys.readouterr().err == ""


def test_require_solvers_explains_a_missing_precice(tmp_path, monkeypatch, capsys):
    from gymprecice.tools.cli import PRECICE_ADVICE

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
    from gymprecice.tools.cli import doctor_report

    missing = requirements.missing_requirements(doctor_report(), ENVIRONMENTS["jet-cylinder"])
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


# -- help, one-line errors -------------------------------------------------------------------


def _commands() -> dict[str, argparse.ArgumentParser]:
    parser = build_parser()
    return next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices


def _help(command: str) -> str:
    return _commands()[command].format_help()


def test_every_help_shows_defaults_and_a_description():
    text = " ".join(_help("train").split())
    for default in ("(default: 100000)", "(default: 1)", "(default: ppo)", "(default: 5)"):
        assert default in text, default
    assert "n_steps 80" in text and "about 21 hours" in text
    for command in ("evaluate", "baseline", "open-loop"):
        text = " ".join(_help(command).split())
        assert "(default: 1)" in text  # --episodes
        assert "quickstart 2 s" in text and "jet-cylinder 10 s" in text
        usage, _, _rest = text.partition("positional arguments")
        assert len(usage.split("]")[-1].strip()) > 40, command  # a description


def test_top_level_help_and_every_command_help_format(capsys):
    """argparse %-formats every help string: a bare "%" in one breaks ``gymprecice --help``."""
    with pytest.raises(SystemExit) as exit_info:
        main(["--help"])
    assert exit_info.value.code == 0
    out = capsys.readouterr().out
    for command, parser in _commands().items():
        assert command in out, command
        # a description is not %-formatted (only help strings are): "%%" would show
        assert "%%" not in parser.format_help(), command
    assert "95 % of their env's reference floor" in " ".join(out.split())


def test_rollouts_default_to_the_environments_own_horizon(tmp_path):
    out = tmp_path / "out"
    quick = from_argv(["baseline", "quickstart", "--double"])
    jet = from_argv(["baseline", "jet-cylinder", "--double"])
    assert build_env_kwargs(quick, ENVIRONMENTS["quickstart"], out)["episode_time"] == 2.0
    assert build_env_kwargs(jet, ENVIRONMENTS["jet-cylinder"], out)["episode_time"] == 10.0
    trained = from_argv(["train", "quickstart", "--double", "--out", str(out)])
    assert "episode_time" not in build_env_kwargs(trained, ENVIRONMENTS["quickstart"], out)
    assert trained.constructor_kwargs == build_env_kwargs(trained, trained.lab_env, out)


def test_without_solvers_and_without_double_one_line_suggests_double(tmp_path, monkeypatch, capsys):
    report = {"ok": False, "checks": [_check("pyprecice", False, required=True)]}
    monkeypatch.setattr("gymprecice.cli.doctor_report", lambda: report)
    monkeypatch.chdir(tmp_path)
    for command in ("train", "baseline"):
        assert main([command, "quickstart"]) == 1
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1, err
        assert "add --double" in err and "pyprecice" in err
    assert list(tmp_path.iterdir()) == []


def test_bad_env_kwargs_are_one_line(tmp_path):
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "gymprecice",
            "baseline",
            "quickstart",
            "--double",
            "--env-kwargs",
            '{"no_such_option": 1}',
        ],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 1
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert "no_such_option" in lines[0] and "--env-kwargs" in lines[0]


def test_cuda_without_cuda_is_refused(tmp_path, monkeypatch):
    import torch

    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)
    monkeypatch.chdir(tmp_path)
    with pytest.raises(
        SystemExit, match=r"--device cuda: .* sees no CUDA device; use --device cpu"
    ):
        main(["train", "quickstart", "--double", "--device", "cuda"])
    assert not (tmp_path / "runs").exists()


def test_batch_size_larger_than_the_rollout_is_clamped_with_a_warning(capsys):
    params = {"algo": "ppo", "n_steps": 16, "batch_size": 80}
    notes = hyperparams.adjust_batch_size(params, 2)
    assert params["batch_size"] == 32
    assert notes and "--batch-size 80" in notes[0] and "training with batch size 32" in notes[0]
    assert "warning: --batch-size 80" in capsys.readouterr().err
    assert hyperparams.adjust_batch_size({"algo": "ppo", "n_steps": 16, "batch_size": 32}, 2) == []


# -- hyperparameters -------------------------------------------------------------------------


def test_hyperparameters_resolve_defaults_then_file_then_flags(tmp_path):
    from gymprecice_lab import hyperparams as hp

    path = tmp_path / "h.yaml"
    path.write_text("gymprecice/Quickstart-v0:\n  n_steps: 40\n  gamma: 0.9\n  policy: MlpPolicy\n")
    from_file = hp.load_hyperparams_file(path, "ppo", ("gymprecice/Quickstart-v0",))
    params = hp.resolve("ppo", from_file, {"gamma": 0.95, "n_steps": None})
    assert (params["n_steps"], params["gamma"], params["n_epochs"]) == (40, 0.95, 10)
    kwargs = hp.model_kwargs(params)
    assert kwargs["policy_kwargs"] == {"net_arch": {"pi": [512, 512], "vf": [512, 512]}}
    assert "net" not in kwargs and "normalize" not in kwargs
    changed = hp.changed_on_resume(params, {**params, "learning_rate": 1e-3})
    assert changed == ["--learning-rate is 0.001 now but 0.0003 in the run being resumed"]
    path.write_text("clip_rangee: 0.1\n")
    with pytest.raises(
        SystemExit, match=r"--hyperparams .*h\.yaml: PPO has no hyperparameter 'clip_rangee'"
    ):
        hp.load_hyperparams_file(path, "ppo", ())
    with pytest.raises(SystemExit, match="--n-steps is a PPO setting"):
        hp.resolve("sac", {}, {"n_steps": 8})


def test_td3_explores_with_action_noise_and_a_file_can_choose_it(tmp_path):
    """SB3's TD3 has no action noise by default: its deterministic policy would explore only
    before learning_starts. gymprecice's default is Gaussian noise of 0.1, as RL Zoo's."""
    from stable_baselines3.common.noise import NormalActionNoise, OrnsteinUhlenbeckActionNoise

    from gymprecice_lab import hyperparams as hp

    noise = hp.model_kwargs(hp.resolve("td3", {}, {}), action_dim=2)["action_noise"]
    assert isinstance(noise, NormalActionNoise)
    assert noise._sigma.tolist() == [0.1, 0.1]
    assert "action_noise" not in hp.model_kwargs(hp.resolve("sac", {}, {}))

    path = tmp_path / "t.yml"
    path.write_text("noise_type: ornstein-uhlenbeck\nnoise_std: 0.3\n")
    params = hp.resolve("td3", hp.load_hyperparams_file(path, "td3", ()), {})
    noise = hp.model_kwargs(params)["action_noise"]
    assert isinstance(noise, OrnsteinUhlenbeckActionNoise) and noise._sigma.tolist() == [0.3]
    path.write_text("noise_type: pink\n")
    with pytest.raises(SystemExit, match=r"t\.yml: noise_type 'pink' is not one of normal"):
        hp.load_hyperparams_file(path, "td3", ())
    path.write_text("noise_type: normal\n")
    with pytest.raises(SystemExit, match=r"t\.yml: noise_type is the action noise of SAC"):
        hp.load_hyperparams_file(path, "ppo", ())


# -- checkpoints -----------------------------------------------------------------------------


def test_only_the_newest_checkpoints_and_the_best_are_kept(tmp_path):
    from gymprecice_lab.training.callbacks import BEST_NAME, prune_checkpoints

    for steps in (10, 20, 30, 40, 50):
        (tmp_path / f"ppo_{steps}_steps.zip").write_text("m")
        (tmp_path / f"ppo_vecnormalize_{steps}_steps.pkl").write_text("s")
    (tmp_path / BEST_NAME).write_text(json.dumps({"name": "ppo_20_steps.zip"}))
    deleted = prune_checkpoints(tmp_path, "ppo", keep=2)
    assert sorted(p.name for p in deleted) == ["ppo_10_steps.zip", "ppo_30_steps.zip"]
    assert sorted(p.name for p in tmp_path.glob("ppo_*_steps.zip")) == [
        "ppo_20_steps.zip",
        "ppo_40_steps.zip",
        "ppo_50_steps.zip",
    ]
    assert not (tmp_path / "ppo_vecnormalize_10_steps.pkl").exists()


# -- manifest and imports --------------------------------------------------------------------


def test_manifest_lists_pyprecice_only_when_importable(tmp_path):
    solvers = {"ok": False, "checks": [_check("pyprecice", False, required=True)]}
    path = manifest.write_manifest(tmp_path, command="baseline", argv=["x"], solvers=solvers)
    data = json.loads(path.read_text())
    assert data["packages"]["pyprecice"] is None
    assert data["source"]["identified_by"] in ("git", "packages")
