"""``gymprecice train / evaluate / baseline / open-loop / plot`` end to end on the test double.

The commands run as a user runs them (``python -m gymprecice ...`` in a working
directory), with 2 parallel environments coupled through gymprecice's preCICE test double
to the scripted fake flow. One recorded run (training, its resumption, three rollouts) is
shared by the tests of this module.
"""

from __future__ import annotations

import csv
import hashlib
import importlib.metadata
import json
import math
import shutil
import signal
import subprocess
import sys
import time
from importlib.resources import files
from pathlib import Path

import numpy as np
import pytest

from gymprecice_lab import plots
from gymprecice_tutorials.jet_cylinder.environment import MAX_FLOW_RATE

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
TRAIN = [
    "train",
    "quickstart",
    "--double",
    "--n-envs",
    "2",
    "--n-steps",
    "8",
    "--batch-size",
    "8",
    "--n-epochs",
    "2",
    "--episode-time",
    "0.1",
    "--net",
    "16,16",
    "--seed",
    "7",
    "--out",
    "train",
]


def _cli(cwd: Path, *args: str, timeout: float = 240) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "gymprecice", *args],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=timeout,
    )


def _ok(proc: subprocess.CompletedProcess[str]) -> str:
    assert proc.returncode == 0, f"exit {proc.returncode}\n{proc.stdout}\n{proc.stderr}"
    return proc.stdout + proc.stderr


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> dict[str, object]:
    root = tmp_path_factory.mktemp("recorded")
    started = time.monotonic()
    first = _ok(_cli(root, *TRAIN, "--timesteps", "32"))
    seconds = time.monotonic() - started
    monitors_after_first = {
        p.name: p.read_text() for p in sorted((root / "train" / "monitor").glob("*.csv"))
    }
    resumed = _ok(_cli(root, *TRAIN, "--timesteps", "48", "--no-progress-bar"))
    rollouts = {}
    for command, extra in (
        ("baseline", []),
        ("evaluate", ["--model", "train", "--episodes", "2", "--baseline", "baseline"]),
        ("open-loop", ["--amplitude", "0.5", "--frequency", "3"]),
    ):
        out = _ok(
            _cli(
                root,
                command,
                "quickstart",
                "--double",
                "--episode-time",
                "0.25",
                "--out",
                command,
                *extra,
            )
        )
        rollouts[command] = out
    return {
        "root": root,
        "train_seconds": seconds,
        "first": first,
        "resumed": resumed,
        "monitors_after_first": monitors_after_first,
        "rollouts": rollouts,
    }


def _monitor_rows(path: Path) -> list[dict[str, str]]:
    lines = path.read_text().splitlines()
    assert lines[0].startswith("#{") and lines[1] == "r,l,t,mean_Cd,mean_Cl,action_rms", lines[:2]
    return list(csv.DictReader(lines[1:]))


def _history(path: Path) -> list[dict[str, str]]:
    with path.open() as handle:
        return list(csv.DictReader(handle))


# -- train -----------------------------------------------------------------------------------


def test_train_runs_ppo_updates_end_to_end(recorded):
    root: Path = recorded["root"]  # type: ignore[assignment]
    train = root / "train"
    assert recorded["train_seconds"] < 120, recorded["train_seconds"]
    assert (train / "model.zip").is_file()
    assert (train / "checkpoints" / "ppo_32_steps.zip").is_file()
    # 32 steps over 2 envs of 4-action episodes: 4 whole episodes per env
    for name, text in recorded["monitors_after_first"].items():  # type: ignore[union-attr]
        rows = list(csv.DictReader(text.splitlines()[1:]))
        assert len(rows) == 4, name
        assert all(int(r["l"]) == 4 and math.isfinite(float(r["r"])) for r in rows)
    # PPO updated: its losses went to TensorBoard
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    events = sorted((train / "tb").rglob("events.out.tfevents.*"))
    assert events
    tags: set[str] = set()
    for path in events:
        acc = EventAccumulator(str(path))
        acc.Reload()
        tags |= set(acc.Tags()["scalars"])
    assert {"train/loss", "train/value_loss", "rollout/ep_rew_mean"} <= tags
    # the fault-tolerant vector env ran the envs (its per-env worker logs)
    assert sorted(p.name for p in (train / "workers").glob("env_*.log")) == [
        "env_0.log",
        "env_1.log",
    ]


def test_train_resumes_from_the_newest_checkpoint(recorded):
    train: Path = recorded["root"] / "train"  # type: ignore[operator]
    assert "resuming from" in recorded["resumed"] and "ppo_32_steps.zip" in recorded["resumed"]
    assert "48 steps" in recorded["resumed"]
    assert (train / "checkpoints" / "ppo_48_steps.zip").is_file()
    for name, before in recorded["monitors_after_first"].items():  # type: ignore[union-attr]
        after = _monitor_rows(train / "monitor" / name)
        assert len(after) == 6  # 4 episodes, then 2 more of the 8 resumed steps per env
        assert (train / "monitor" / name).read_text().startswith(before)


def test_manifest_records_what_made_the_run(recorded):
    train: Path = recorded["root"] / "train"  # type: ignore[operator]
    manifest = json.loads((train / "manifest.json").read_text())
    assert manifest["command"] == "train"
    assert manifest["argv"][1:3] == ["train", "quickstart"] and "--double" in manifest["argv"]
    assert manifest["seeds"] == {"seed": 7, "env_seeds": [7, 8]}
    for dist in ("gymprecice-core", "gymprecice-tutorials", "stable-baselines3", "torch"):
        assert manifest["packages"][dist] == importlib.metadata.version(dist)
    checks = {c["name"]: c for c in manifest["solvers"]["checks"]}
    assert "pyprecice" in checks and "python" in checks
    assert manifest["settings"]["double"] is True
    assert manifest["settings"]["env_id"] == "gymprecice/Quickstart-v0"
    assert manifest["result"]["timesteps"] == 48
    case = Path(manifest["case_dir"])
    hashes = manifest["config_files"]
    assert {"gymprecice-config.json", "precice-config.xml", "fluid-fake/fake-flow.json"} <= set(
        hashes
    )
    for rel, digest in hashes.items():
        assert hashlib.sha256((case / rel).read_bytes()).hexdigest() == digest


# -- rollouts --------------------------------------------------------------------------------


def test_baseline_is_uncontrolled_and_open_loop_is_a_sine(recorded):
    root: Path = recorded["root"]  # type: ignore[assignment]
    baseline = _history(root / "baseline" / "history.csv")
    assert len(baseline) == 10  # 0.25 s of 0.025 s actions
    assert all(float(r["action_0"]) == 0.0 for r in baseline)
    sine = _history(root / "open-loop" / "history.csv")
    for row in sine:
        expected = 0.5 * MAX_FLOW_RATE * math.sin(2 * math.pi * 3.0 * float(row["start"]))
        assert float(row["action_0"]) == pytest.approx(expected, rel=1e-5, abs=1e-12)
    coefficients = _history(root / "baseline" / "coefficients.csv")
    assert len(coefficients) == 500  # every solver step: 10 actions x 50 steps
    summary = json.loads((root / "baseline" / "summary.json").read_text())
    assert summary["episodes"][0]["steps"] == 10
    assert summary["episodes"][0]["mean_Cd"] == pytest.approx(
        np.mean([float(r["Cd"]) for r in baseline])
    )


def test_evaluate_runs_the_trained_policy_deterministically(recorded):
    root: Path = recorded["root"]  # type: ignore[assignment]
    manifest = json.loads((root / "evaluate" / "manifest.json").read_text())
    assert manifest["settings"]["deterministic"] is True
    # a training directory gives its kept model, the best of its validations
    assert Path(manifest["settings"]["model"]) == (root / "train" / "best_model.zip").resolve()
    rows = _history(root / "evaluate" / "history.csv")
    assert len(rows) == 20  # two episodes of 10 actions
    rows = [r for r in rows if r["episode"] == "0"]
    actions = np.array([float(r["action_0"]) for r in rows])
    assert len(rows) == 10 and np.all(np.abs(actions) <= MAX_FLOW_RATE * (1 + 1e-6))
    # rerunning gives the same actions: the policy's mean, not samples
    again = _ok(
        _cli(
            root,
            "evaluate",
            "quickstart",
            "--double",
            "--episode-time",
            "0.1",
            "--model",
            "train/best_model.zip",
            "--out",
            "evaluate-again",
        )
    )
    assert "1 episode(s)" in again
    first4 = actions[:4]
    again4 = [float(r["action_0"]) for r in _history(root / "evaluate-again" / "history.csv")]
    assert np.allclose(first4, again4, rtol=1e-6, atol=0)


# -- plot ------------------------------------------------------------------------------------


def _assert_png(path: Path) -> None:
    import matplotlib.image

    data = path.read_bytes()
    assert data[:8] == PNG_SIGNATURE, path
    assert len(data) > 10_000, (path, len(data))
    pixels = matplotlib.image.imread(path)
    assert pixels.shape[0] > 200 and pixels.shape[1] > 400
    assert float(np.std(pixels[..., :3])) > 0.01  # something is drawn


def test_plot_draws_reward_actions_and_coefficients(recorded):
    root: Path = recorded["root"]  # type: ignore[assignment]
    out = _ok(
        _cli(
            root,
            "plot",
            "train",
            "evaluate",
            "open-loop",
            "--baseline",
            "baseline",
            "--out",
            "figs",
        )
    )
    names = {"reward.png", "actions.png", "coefficients.png"}
    assert {Path(line).name for line in out.split()} >= names
    for name in names:
        _assert_png(root / "figs" / name)


def test_reward_curve_falls_back_to_tensorboard(recorded, tmp_path):
    train = tmp_path / "train"
    shutil.copytree(recorded["root"] / "train" / "tb", train / "tb")  # type: ignore[operator]
    curve = plots.load_training_curve(train)
    assert curve is not None and curve["source"] == "tensorboard"
    steps, values = curve["per_env"][0]
    assert len(steps) >= 2 and np.all(np.isfinite(values))
    png = plots.plot_reward([train], tmp_path / "figs")
    assert png is not None
    _assert_png(png)


def test_plot_with_nothing_to_draw_fails(tmp_path):
    (tmp_path / "empty").mkdir()
    proc = _cli(tmp_path, "plot", "empty")
    assert proc.returncode == 1 and "nothing to draw" in proc.stderr


def test_ctrl_c_saves_the_policy_and_the_same_command_resumes(tmp_path):
    """SIGINT mid-training: exit 130 with model and checkpoint saved, nothing lost."""
    args = [*TRAIN, "--timesteps", "100000", "--no-progress-bar"]
    proc = subprocess.Popen(
        [sys.executable, "-m", "gymprecice", *args],
        cwd=tmp_path,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        # as typed in a terminal: a runner started in the background ignores SIGINT, and
        # Python keeps an ignored SIGINT ignored
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    try:
        monitors = tmp_path / "train" / "monitor"
        deadline = time.monotonic() + 180
        while time.monotonic() < deadline and proc.poll() is None:
            if any(len(p.read_text().splitlines()) > 2 for p in monitors.glob("*.csv")):
                break  # an episode done: the learner is in the middle of its first rollout
            time.sleep(0.2)
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=120)
    finally:
        proc.kill()
    assert proc.returncode == 130, out + err
    assert "interrupted (SIGINT) after" in err and "run the same command again to resume" in err
    assert (tmp_path / "train" / "model.zip").is_file()
    saved = sorted((tmp_path / "train" / "checkpoints").glob("ppo_*_steps.zip"))
    assert saved and int(saved[-1].name.split("_")[1]) > 0


# -- what a run records (issue: a training command a researcher trusts) ---------------------


def test_every_segment_is_recorded_with_source_and_model_checksum(recorded):
    train: Path = recorded["root"] / "train"  # type: ignore[operator]
    manifest = json.loads((train / "manifest.json").read_text())
    first, resumed = manifest["segments"]
    assert first["result"]["timesteps"] == 32 and first["result"]["resumed_from"] is None
    assert resumed["result"]["timesteps"] == 48
    assert resumed["result"]["resumed_from"].endswith("ppo_32_steps.zip")
    assert resumed["argv"][-3:] == ["--timesteps", "48", "--no-progress-bar"]
    used = manifest["settings"]["hyperparams"]
    assert (used["algo"], used["n_steps"], used["batch_size"], used["net"]) == (
        "ppo",
        8,
        8,
        [16, 16],
    )
    assert json.loads((train / "hyperparams.json").read_text())["n_steps"] == 8
    digest = hashlib.sha256((train / "model.zip").read_bytes()).hexdigest()
    assert manifest["result"]["model_sha256"] == digest
    assert manifest["result"]["device"] == "cpu"
    assert set(manifest["source"]) == {"git", "identified_by"}
    assert manifest["source"]["identified_by"] in ("git", "packages")


def test_resume_with_other_hyperparameters_is_refused_naming_the_flag(recorded):
    root: Path = recorded["root"]  # type: ignore[assignment]
    before = (root / "train" / "manifest.json").read_text()
    args = [a if a != "8" else "16" for a in TRAIN]  # --n-steps 16 --batch-size 16
    proc = _cli(root, *args, "--timesteps", "64")  # as typed: one line, warnings and all
    assert proc.returncode == 1
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert "--n-steps is 16 now but 8 in the run being resumed" in lines[0]
    assert "--batch-size is 16 now but 8" in lines[0] and "--fresh" in lines[0]
    assert (root / "train" / "manifest.json").read_text() == before


def test_monitor_time_axis_keeps_increasing_across_a_resume(recorded):
    train: Path = recorded["root"] / "train"  # type: ignore[operator]
    for path in sorted((train / "monitor").glob("*.csv")):
        rows = _monitor_rows(path)
        times = [float(r["t"]) for r in rows]
        assert times == sorted(times), times  # t of resumed episodes continues the first's
        assert all(math.isfinite(float(r["mean_Cd"])) for r in rows)
        assert all(float(r["action_rms"]) >= 0 for r in rows)


def test_env_metrics_and_progress_csv_are_logged(recorded):
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    train: Path = recorded["root"] / "train"  # type: ignore[operator]
    tags: set[str] = set()
    for path in sorted((train / "tb").rglob("events.out.tfevents.*")):
        acc = EventAccumulator(str(path))
        acc.Reload()
        tags |= set(acc.Tags()["scalars"])
    assert {"env/mean_Cd", "env/mean_Cl", "env/action_rms"} <= tags
    with (train / "progress.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    steps = [int(r["time/total_timesteps"]) for r in rows if r.get("time/total_timesteps")]
    assert steps[-1] == 48 and 32 in steps  # both segments, merged
    assert not list(train.glob("progress.*.csv"))


def test_evaluate_reports_mean_and_spread_and_change_against_the_baseline(recorded):
    root: Path = recorded["root"]  # type: ignore[assignment]
    summary = json.loads((root / "evaluate" / "summary.json").read_text())
    cds = [e["mean_Cd"] for e in summary["episodes"]]
    assert len(cds) == 2
    stats = summary["over_episodes"]["mean_Cd"]
    assert stats["mean"] == pytest.approx(np.mean(cds)) and stats["n"] == 2
    assert stats["std"] == pytest.approx(np.std(cds))
    base = json.loads((root / "baseline" / "summary.json").read_text())
    ref = base["over_episodes"]["mean_Cd"]["mean"]
    assert summary["change_percent"]["mean_Cd"] == pytest.approx(
        100 * (stats["mean"] - ref) / abs(ref)
    )
    out = recorded["rollouts"]["evaluate"]  # type: ignore[index]
    assert "2 episode(s)" in out and "mean Cd" in out and "±" in out
    assert "against the baseline" in out


def test_evaluate_states_drag_and_lift_over_every_solver_step(recorded):
    """The claim's own statistics: mean Cd and mean |Cl| of coefficients.csv, per episode."""
    root: Path = recorded["root"]  # type: ignore[assignment]
    summary = json.loads((root / "evaluate" / "summary.json").read_text())
    with (root / "evaluate" / "coefficients.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    for episode in summary["episodes"]:
        mine = [r for r in rows if int(r["episode"]) == episode["episode"]]
        assert mine
        cd = np.array([float(r["Cd"]) for r in mine])
        cl = np.array([float(r["Cl"]) for r in mine])
        assert episode["series_mean_Cd"] == pytest.approx(cd.mean())
        assert episode["series_mean_abs_Cl"] == pytest.approx(np.abs(cl).mean())
    base = json.loads((root / "baseline" / "summary.json").read_text())
    ref = base["over_episodes"]["series_mean_abs_Cl"]["mean"]
    ours = summary["over_episodes"]["series_mean_abs_Cl"]["mean"]
    assert summary["change_percent"]["series_mean_abs_Cl"] == pytest.approx(
        100 * (ours - ref) / abs(ref)
    )
    out = recorded["rollouts"]["evaluate"]  # type: ignore[index]
    lines = [x for x in out.splitlines() if x.startswith("gymprecice evaluate:")]
    assert "the kept model" in lines[0]  # which model of the training run it took
    line = next(x for x in lines if "episode(s)" in x)
    assert "mean |Cl|" in line and "over every solver step" in line
    # no relative change of the return: it is about zero uncontrolled by construction
    assert line.split(", mean Cd")[0].count("against the baseline") == 0


def test_evaluate_a_training_dir_without_model_uses_its_newest_checkpoint(recorded, tmp_path):
    shutil.copytree(recorded["root"] / "train" / "checkpoints", tmp_path / "killed" / "checkpoints")  # type: ignore[operator]
    out = _ok(
        _cli(
            tmp_path,
            "evaluate",
            "quickstart",
            "--double",
            "--episode-time",
            "0.05",
            "--model",
            "killed",
        )
    )
    assert "newest checkpoint" in out and "ppo_48_steps.zip" in out
    manifest = json.loads(
        (tmp_path / "runs" / "quickstart" / "evaluate" / "manifest.json").read_text()
    )
    assert manifest["settings"]["model"].endswith("ppo_48_steps.zip")


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP])
def test_sigterm_and_sighup_save_like_ctrl_c(tmp_path, sig):
    """A cluster's preemption signal: the model and a checkpoint are saved and recorded."""
    args = [*TRAIN, "--timesteps", "100000", "--no-progress-bar"]
    proc = subprocess.Popen(
        [sys.executable, "-m", "gymprecice", *args],
        cwd=tmp_path,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        monitors = tmp_path / "train" / "monitor"
        deadline = time.monotonic() + 180
        while time.monotonic() < deadline and proc.poll() is None:
            if any(len(p.read_text().splitlines()) > 2 for p in monitors.glob("*.csv")):
                break  # an episode done, as for Ctrl-C
            time.sleep(0.2)
        proc.send_signal(sig)
        out, err = proc.communicate(timeout=120)
    finally:
        proc.kill()
    assert proc.returncode == 128 + sig, out + err
    name = signal.Signals(sig).name
    assert f"interrupted ({name})" in err and "run the same command again to resume" in err
    train = tmp_path / "train"
    manifest = json.loads((train / "manifest.json").read_text())
    assert manifest["result"]["interrupted"] == name
    steps = manifest["result"]["timesteps"]
    assert steps > 0 and (train / "checkpoints" / f"ppo_{steps}_steps.zip").is_file()
    assert (
        manifest["result"]["model_sha256"]
        == hashlib.sha256((train / "model.zip").read_bytes()).hexdigest()
    )


def test_sac_with_a_hyperparameter_file_normalize_and_evaluation(tmp_path):
    """--algo sac, --hyperparams (copied), --normalize and --eval-freq on the double; the
    shipped helper and evaluate load the model with its normalisation."""
    (tmp_path / "sac.yml").write_text(
        "gymprecice/Quickstart-v0:\n  learning_starts: 4\n  buffer_size: 200\n  batch_size: 8\n"
        "  net: [16, 16]\n"
    )
    common = ["quickstart", "--double", "--episode-time", "0.1", "--seed", "3"]
    _ok(
        _cli(
            tmp_path,
            "train",
            *common,
            "--algo",
            "sac",
            "--hyperparams",
            "sac.yml",
            "--normalize",
            "--timesteps",
            "8",  # two episodes, updates from step 5, the evaluation at the end
            "--eval-freq",
            "8",
            "--n-eval-episodes",
            "1",
            "--no-progress-bar",
            "--out",
            "sac",
        )
    )
    run = tmp_path / "sac"
    assert (run / "hyperparams.yaml").read_text() == (tmp_path / "sac.yml").read_text()
    used = json.loads((run / "hyperparams.json").read_text())
    assert (used["algo"], used["learning_starts"], used["normalize"]) == ("sac", 4, True)
    for name in ("model.zip", "model_vecnormalize.pkl", "best_model.zip"):
        assert (run / name).is_file(), name
    assert (run / "best_model_vecnormalize.pkl").is_file()
    assert (run / "checkpoints" / "sac_vecnormalize_8_steps.pkl").is_file()
    out = _ok(_cli(tmp_path, "evaluate", *common, "--model", "sac/best_model.zip", "--out", "ev"))
    assert "1 episode(s)" in out
    manifest = json.loads((tmp_path / "ev" / "manifest.json").read_text())
    assert manifest["settings"]["normalization"].endswith("best_model_vecnormalize.pkl")

    from stable_baselines3 import SAC
    from stable_baselines3.common.vec_env import VecNormalize

    from gymprecice_lab.common.wrapped_env import load_policy

    venv, model = load_policy(
        run, "quickstart", double=True, episode_time=0.1, run_root=str(tmp_path / "helper")
    )
    try:
        assert isinstance(model, SAC) and isinstance(venv, VecNormalize)
        assert venv.training is False
        assert np.allclose(venv.action_space.low, -1) and np.allclose(venv.action_space.high, 1)
        obs = venv.reset()
        action, _ = model.predict(obs, deterministic=True)
        _, _, _, infos = venv.step(action)
        applied = infos[0]["action"][0]
        assert applied == pytest.approx(float(action[0][0]) * MAX_FLOW_RATE, rel=1e-4)
    finally:
        venv.close()


def test_plot_writes_pdf_and_svg_with_labels_units_bounds_and_mean_cd(recorded, gymprecice_refused):
    root: Path = recorded["root"]  # type: ignore[assignment]
    common = ["plot", "evaluate", "open-loop", "--baseline", "baseline"]
    out = _ok(_cli(root, *common, "--format", "pdf", "--out", "pdf"))
    assert {Path(line).name for line in out.split()} >= {"actions.pdf", "coefficients.pdf"}
    assert (root / "pdf" / "actions.pdf").read_bytes()[:5] == b"%PDF-"
    _ok(_cli(root, *common, "--format", "svg", "--labels", "PPO,sine", "--out", "svg"))
    actions = (root / "svg" / "actions.svg").read_text()
    coefficients = (root / "svg" / "coefficients.svg").read_text()
    # labels, units, applied scheme, the episode drawn
    for text in ("PPO", "sine", "m³/s", "(ramp)", "episode 0"):
        assert text in actions, text
    assert "mean Cd" in coefficients and "% vs baseline" in coefficients
    _ok(_cli(root, "plot", "evaluate", "--episode", "1", "--format", "svg", "--out", "ep1"))
    assert "episode 1" in (root / "ep1" / "actions.svg").read_text()
    status, err = gymprecice_refused(root, "plot", "baseline", "--episode", "1")
    assert status == 1 and "--episode 1: the run has episodes 0" in err
    status, err = gymprecice_refused(root, *common, "--labels", "only-one")
    assert status == 2 and "one per RUN" in err


def test_applied_action_ramps_from_the_previous_action():
    t, v = plots.applied_action(
        np.array([0.0, 1.0]), np.array([1.0, 2.0]), np.array([1.0, -1.0]), "ramp", 2
    )
    assert np.allclose(t, [0.0, 0.5, 1.0, 1.5, 2.0])
    assert np.allclose(v, [0.0, 0.5, 1.0, 0.0, -1.0])
    t, v = plots.applied_action(np.array([0.0]), np.array([1.0]), np.array([2.0]), "hold", 2)
    assert np.allclose(v, [2.0, 2.0, 2.0])


def test_one_interpolated_window_per_action_is_drawn_as_a_ramp(tmp_path):
    # coupling="action": core writes each action once (hold, 1 window); preCICE's
    # waveform-degree 1 ramps it across the window, which is what the solver applies
    case = tmp_path / "case"
    case.mkdir()
    (tmp_path / "manifest.json").write_text(json.dumps({"case_dir": str(case)}))
    config = {"precice": {"config_file": "precice-config.xml"}, "actions": {"windows": 1}}
    (case / "gymprecice-config.json").write_text(json.dumps(config))
    packaged = files("gymprecice_tutorials") / "cases" / "jet_cylinder_fast" / "precice-config.xml"
    xml = packaged.read_text()
    assert 'name="Velocity" waveform-degree="1"' in xml  # the Controller writes Velocity
    (case / "precice-config.xml").write_text(xml)
    assert plots._action_scheme(tmp_path) == ("ramp", 1)
    (case / "precice-config.xml").write_text(
        xml.replace('waveform-degree="1"', 'waveform-degree="0"')
    )
    assert plots._action_scheme(tmp_path) == ("hold", 1)
    # a run directory moved elsewhere still finds its own copy of the case
    moved = tmp_path / "moved"
    (moved / "envs" / "cases").mkdir(parents=True)
    shutil.copytree(case, moved / "envs" / "cases" / "case")  # waveform-degree 0 now
    (moved / "manifest.json").write_text(json.dumps({"case_dir": str(tmp_path / "gone" / "case")}))
    assert plots._action_scheme(moved) == ("hold", 1)
    (moved / "envs" / "cases" / "case" / "precice-config.xml").write_text(xml)
    assert plots._action_scheme(moved) == ("ramp", 1)
    config["actions"] = {"windows": 50, "scheme": "ramp"}
    (case / "gymprecice-config.json").write_text(json.dumps(config))
    assert plots._action_scheme(tmp_path) == ("ramp", 50)


def test_evaluate_under_sensor_noise_is_seeded_and_bad_wrappers_are_refused(
    recorded, gymprecice_refused
):
    """A shipped or trained policy is tested for robustness without retraining."""
    root: Path = recorded["root"]  # type: ignore[assignment]
    common = ["evaluate", "quickstart", "--double", "--episode-time", "0.1"]
    common += ["--model", "train/model.zip"]
    noisy = ["--wrap", "sensor_noise:std=0.5,mode=relative", "--wrap", "delay:steps=1"]
    for out in ("noisy-a", "noisy-b"):
        _ok(_cli(root, *common, *noisy, "--out", out))
    a = [float(r["action_0"]) for r in _history(root / "noisy-a" / "history.csv")]
    b = [float(r["action_0"]) for r in _history(root / "noisy-b" / "history.csv")]
    clean = [float(r["action_0"]) for r in _history(root / "evaluate-again" / "history.csv")]
    assert a == b  # the same seed, the same noise
    assert a[0] == 0.0  # the delay: the first step applies the initial (zero) action
    assert not np.allclose(a[1:], clean[: len(a) - 1])
    manifest = json.loads((root / "noisy-a" / "manifest.json").read_text())
    assert manifest["settings"]["robustness"] == {
        "delay": {"steps": 1},
        "sensor_noise": {"std": 0.5, "mode": "relative"},
    }
    status, err = gymprecice_refused(
        root, *common, "--wrap", "sensor_noise:sdt=0.5", "--out", "bad"
    )
    assert status == 2
    assert "unknown option sensor_noise.sdt (did you mean 'std'?)" in err
    assert not (root / "bad").exists()
