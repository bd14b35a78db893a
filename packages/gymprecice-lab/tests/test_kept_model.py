"""The model a training run keeps: the best on validation starts, never on held-out ones.

Validation starts choose among models; held-out starts judge the model chosen. These tests
pin that split down: each tutorial's validation starts are disjoint from its held-out
ones, an env that declares none gets seeds far from the test seeds, a training run on the
test double scores its policy from the validation starts alone and keeps the best with
its record, and the commands that take a training run take the kept model unless
``--model final`` says otherwise, saying which.
"""

from __future__ import annotations

import json
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from gymprecice_lab.common.kept_model import choose_model, kept_summary, read_kept
from gymprecice_lab.common.starts import (
    VALIDATION_SEED,
    ValidationStarts,
    evaluation_starts,
    held_out_starts,
    validation_options,
    validation_starts,
)
from gymprecice_lab.training.validation import side_by_side

TUTORIALS_WITH_STARTS = (
    "gymprecice/PerpendicularFlapFast-v0",
    "gymprecice/HeatedPlateFast-v0",
    "gymprecice/TwoFlapsFast-v0",
    "gymprecice/JetCylinderFast-v0",
    "gymprecice/RotatingCylinderFast-v0",
)


@pytest.mark.parametrize("env_id", TUTORIALS_WITH_STARTS)
def test_every_tutorial_declares_validation_starts_disjoint_from_its_held_out_ones(
    env_id, tmp_path
):
    import gymprecice  # noqa: F401  (registers the ids)

    env = gym.make(env_id, double=True, run_root=str(tmp_path))
    try:
        validation, held_out = validation_starts(env), held_out_starts(env)
        assert validation and held_out
        assert not set(validation) & set(held_out)
        seed, options = validation_options(env, 1)
        assert (seed, options) == (None, {"split": "validation", "start": 1})
    finally:
        env.close()


def test_an_env_without_declared_starts_gets_seeds_far_from_its_test_seeds(tmp_path):
    import gymprecice  # noqa: F401

    env = gym.make("gymprecice/Quickstart-v0", double=True, run_root=str(tmp_path))
    try:
        labels = validation_starts(env)
        assert labels == tuple(f"validation seed {VALIDATION_SEED + k}" for k in range(3))
        assert not set(labels) & set(evaluation_starts(env))
        # its test starts are the evaluation split's first seeds; validation takes others
        assert validation_options(env, 4) == (VALIDATION_SEED + 1, {"split": "eval"})
    finally:
        env.close()


def test_flap_validation_gusts_are_fixed_and_off_the_training_grid():
    from gymprecice_tutorials.perpendicular_flap.fast import (
        EVAL_GUSTS,
        GUST_STEP,
        VALIDATION_GUSTS,
    )

    assert not set(VALIDATION_GUSTS) & set(EVAL_GUSTS)
    for g in VALIDATION_GUSTS:
        for height in (g.first, g.second):
            steps = height / GUST_STEP
            assert abs(steps - round(steps)) < 1e-9  # whole steps: training draws half steps


def test_a_split_of_validation_starts_between_envs_must_cover_each_start_once():
    class Spy(gym.Env):
        observation_space = gym.spaces.Box(-1, 1, (1,))
        action_space = gym.spaces.Box(-1, 1, (1,))
        validation_starts = ("a", "b", "c", "d")

        def __init__(self):
            self.seen = []

        def reset(self, *, seed=None, options=None):
            self.seen.append(options)
            return np.zeros(1, np.float32), {}

    spy = Spy()
    wrapped = ValidationStarts(spy, part=1, parts=2)
    for _ in range(4):
        wrapped.reset()
    assert [o["start"] for o in spy.seen] == [1, 3, 1, 3]
    with pytest.raises(ValueError, match="cannot be split in 3 parts"):
        ValidationStarts(Spy(), part=0, parts=3)
    assert [side_by_side(s, 2) for s in (1, 2, 3, 4)] == [1, 2, 1, 2]


def test_choose_model_takes_the_kept_model_and_says_which(tmp_path):
    run = tmp_path / "run"
    (run / "eval").mkdir(parents=True)
    (run / "model.zip").write_bytes(b"final")
    (run / "manifest.json").write_text("{}")
    path, note = choose_model(run)
    assert path == run / "model.zip" and "no kept model" in note
    (run / "best_model.zip").write_bytes(b"kept")
    record = {"mean_return": -1.5, "timesteps": 800, "starts": ["a", "b"]}
    record["seconds_from_command"] = 551.0
    (run / "eval" / "best.json").write_text(json.dumps(record))
    path, note = choose_model(run)
    assert path == run / "best_model.zip"
    assert "kept model" in note and "step 800" in note and "9 min 11 s" in note
    assert choose_model(run, "final") == (
        run / "model.zip",
        f"the final model {run / 'model.zip'} (--model final)",
    )
    assert read_kept(run)["timesteps"] == 800
    assert "2 validation start(s)" in kept_summary(record)
    with pytest.raises(ValueError, match="kept or final"):
        choose_model(run, "best")


@pytest.mark.slow
def test_training_chooses_on_validation_starts_and_never_on_held_out_ones(tmp_path, monkeypatch):
    """A short SAC run of the flap on the test double, in this process (``--vec-env
    dummy``), with every reset's options recorded: the validation env takes only the
    validation gusts, nothing resets to a held-out gust, and the kept model's record
    names the starts it was scored on. About 20 s."""
    from gymprecice.tools.cli import main
    from gymprecice_tutorials.perpendicular_flap.fast import (
        VALIDATION_GUSTS,
        PerpendicularFlapFastEnv,
    )

    resets: list[dict] = []
    original = PerpendicularFlapFastEnv.reset

    def spy(self, *, seed=None, options=None):
        resets.append(dict(options or {}))
        return original(self, seed=seed, options=options)

    monkeypatch.setattr(PerpendicularFlapFastEnv, "reset", spy)
    monkeypatch.chdir(tmp_path)
    (tmp_path / "sac.yml").write_text(
        "gymprecice/PerpendicularFlapFast-v0:\n  learning_starts: 4\n  batch_size: 8\n"
        "  net: [16, 16]\n"
    )
    status = main(
        [
            "train",
            "perpendicular-flap-fast",
            "--double",
            "--env-kwargs",
            '{"episode_time": 0.5, "settle_time": 0.2}',
            "--algo",
            "sac",
            "--hyperparams",
            "sac.yml",
            "--timesteps",
            "20",
            "--checkpoint-every",
            "10",
            "--vec-env",
            "dummy",
            "--no-progress-bar",
            "--out",
            "run",
        ]
    )
    assert status == 0
    splits = [r.get("split", "train") for r in resets]
    assert "eval" not in splits
    validations = [r for r in resets if r.get("split") == "validation"]
    assert {r["start"] for r in validations} == set(range(len(VALIDATION_GUSTS)))
    record = read_kept(tmp_path / "run")
    assert record is not None
    assert record["starts"] == list(PerpendicularFlapFastEnv.validation_starts.fget(None))
    assert len(record["returns"]) == len(VALIDATION_GUSTS)
    evaluations = np.load(tmp_path / "run" / "eval" / "evaluations.npz")
    assert list(evaluations["timesteps"]) == [10, 20]  # every checkpoint, the last one too
    best = int(np.argmax(evaluations["results"].mean(axis=1)))
    assert record["timesteps"] == [10, 20][best]
    # one segment: its training time is its time from the command
    assert record["seconds_of_training"] == pytest.approx(record["seconds_from_command"], abs=0.2)


def test_time_to_floor_scans_the_kept_model_by_default(tmp_path):
    from gymprecice_lab.benchmarking.time_to_floor import candidates

    run = tmp_path / "run"
    (run / "eval").mkdir(parents=True)
    (run / "checkpoints").mkdir()
    (run / "manifest.json").write_text(json.dumps({"segments": [{"started_at": 1000.0}]}))
    for steps in (800, 1600):
        (run / "checkpoints" / f"sac_{steps}_steps.zip").write_bytes(b"x")
    (run / "model.zip").write_bytes(b"x")
    with pytest.raises(FileNotFoundError, match="--model final"):
        candidates(run, "kept")
    (run / "best_model.zip").write_bytes(b"x")
    (run / "eval" / "best.json").write_text(
        json.dumps({"mean_return": -1.0, "timesteps": 800, "saved_at": 1551.0})
    )
    (kept,) = candidates(run, "kept")
    assert (kept.steps, kept.model.name, kept.seconds) == (800, "best_model.zip", 551.0)
    (final,) = candidates(run, "final")
    assert (final.steps, final.model.name) == (1600, "model.zip")
    assert [c.steps for c in candidates(run, "checkpoints")] == [800, 1600]


def test_model_option_takes_kept_or_final_and_a_path_as_the_policy():
    from gymprecice.tools.cli import build_parser

    parser = build_parser()
    args = parser.parse_args(["evaluate", "quickstart", "--model", "final"])
    assert (args.model, args.policy) == ("final", None)
    args = parser.parse_args(["evaluate", "quickstart", "--model", "runs/x/model.zip"])
    assert (args.model, args.policy) == ("kept", "runs/x/model.zip")
    args = parser.parse_args(["ship-policy", "runs/x", "--model", "final"])
    assert args.model == "final"
    with pytest.raises(SystemExit):
        parser.parse_args(["ship-policy", "runs/x", "--model", "runs/y"])


def test_openfoam_snapshot_library_keeps_a_validation_set_apart():
    from gymprecice_openfoam.case import split_snapshots

    names = ["4.7", "4.74", "4.78", "4.82", "4.86", "4.9", "4.94", "4.98"]
    split = split_snapshots(names, {"validation_fraction": 0.25})
    assert split == {
        "train": ["4.7", "4.78", "4.86", "4.94"],
        "eval": ["4.82", "4.98"],
        "validation": ["4.74", "4.9"],
    }
    assert split_snapshots(names, {})["eval"] == split["eval"]  # held-out starts unchanged


@pytest.mark.slow
@pytest.mark.waits
def test_validation_runs_beside_a_normalised_overlapped_learner(tmp_path):
    """scripts/sac-overlap.yml's recipe on the test double (normalisation, updates overlapped
    with the solvers, two envs): the validation envs run side by side, one per
    validation start, and the kept model keeps its normalisation. SB3 syncs the
    statistics by walking both wrapper chains in step, which the overlapped learner's
    extra layer broke. About 35 s."""
    import subprocess
    import sys

    root = Path(__file__).resolve().parents[3]
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "gymprecice",
            "train",
            "jet-cylinder-fast",
            "--double",
            "--n-envs",
            "2",
            "--normalize",
            "--algo",
            "sac",
            "--hyperparams",
            str(root / "scripts" / "sac-overlap.yml"),
            "--timesteps",
            "40",
            "--checkpoint-every",
            "20",
            "--episode-time",
            "0.25",
            "--no-progress-bar",
            "--out",
            "run",
        ],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    run = tmp_path / "run"
    assert (run / "best_model_vecnormalize.pkl").is_file()
    assert sorted(p.name for p in (run / "eval").glob("env_*.monitor.csv")) == [
        "env_0.monitor.csv",
        "env_1.monitor.csv",
    ]
    assert read_kept(run)["starts"] == ["t = 4.74 s", "t = 4.9 s"]


def test_stop_at_ends_training_at_the_first_validation_reaching_it_and_a_rerun_trains_no_more(
    tmp_path, monkeypatch, capsys
):
    """``--stop-at``: a score every validation reaches stops a 40-step SAC run of the flap
    on the test double at its first validation (step 10), whose model is the kept one; the
    manifest says so, the benchmark counts the seed as trained, and the same command
    again trains no further. About 15 s."""
    from gymprecice.tools.cli import main
    from gymprecice_lab.benchmarking.seed_training import trained
    from gymprecice_lab.cli.settings import from_argv

    monkeypatch.chdir(tmp_path)
    (tmp_path / "sac.yml").write_text(
        "gymprecice/PerpendicularFlapFast-v0:\n  learning_starts: 4\n  batch_size: 8\n"
        "  net: [16, 16]\n"
    )
    argv = [
        *("train", "perpendicular-flap-fast", "--double"),
        *("--env-kwargs", '{"episode_time": 0.5, "settle_time": 0.2}'),
        *("--algo", "sac", "--hyperparams", "sac.yml", "--timesteps", "40"),
        *("--checkpoint-every", "10", "--stop-at=-1e9"),
        *("--vec-env", "dummy", "--no-progress-bar", "--out", "run"),
    ]
    assert main(argv) == 0
    said = capsys.readouterr().out
    run = tmp_path / "run"
    assert "stopped: the validation at step 10 scored" in said
    assert list(np.load(run / "eval" / "evaluations.npz")["timesteps"]) == [10]
    result = json.loads((run / "manifest.json").read_text())["result"]
    assert result["timesteps"] == 10
    assert result["stopped_at"]["timesteps"] == read_kept(run)["timesteps"] == 10
    assert trained(run, 40) and trained(run, 40, from_argv(argv).stop_at)
    # a benchmark that now stops higher than the score this run stopped at trains it on
    assert not trained(run, 40, 1e9)

    assert main(argv) == 0
    assert "not training on" in capsys.readouterr().out
    assert json.loads((run / "manifest.json").read_text())["result"]["timesteps"] == 10


def test_a_run_stopped_during_a_validation_validates_that_checkpoint_when_resumed(
    tmp_path, monkeypatch, capsys
):
    """A SIGTERM while the step-10 validation runs ends the run with that step's
    checkpoint saved and no validation of it; the same command validates it before it
    trains on, so the checkpoint is still a candidate for the kept model (and for
    ``--stop-at``). About 15 s on the test double."""
    import signal

    from stable_baselines3.common.callbacks import EvalCallback

    from gymprecice.tools.cli import main
    from gymprecice_lab.training.callbacks import Interrupted

    monkeypatch.chdir(tmp_path)
    (tmp_path / "sac.yml").write_text(
        "gymprecice/PerpendicularFlapFast-v0:\n  learning_starts: 4\n  batch_size: 8\n"
        "  net: [16, 16]\n"
    )
    argv = [
        *("train", "perpendicular-flap-fast", "--double"),
        *("--env-kwargs", '{"episode_time": 0.5, "settle_time": 0.2}'),
        *("--algo", "sac", "--hyperparams", "sac.yml", "--timesteps", "20"),
        *("--checkpoint-every", "10", "--stop-at=-1e9"),
        *("--vec-env", "dummy", "--no-progress-bar", "--out", "run"),
    ]
    original = EvalCallback._on_step

    def stopped_mid_validation(self):
        if self.eval_freq > 0 and self.n_calls % self.eval_freq == 0:
            raise Interrupted(signal.SIGTERM)
        return original(self)

    monkeypatch.setattr(EvalCallback, "_on_step", stopped_mid_validation)
    main(argv)
    run = tmp_path / "run"
    assert (run / "checkpoints" / "sac_10_steps.zip").is_file()
    assert read_kept(run) is None
    monkeypatch.setattr(EvalCallback, "_on_step", original)
    capsys.readouterr()

    assert main(argv) == 0
    said = capsys.readouterr().out
    assert "the resumed checkpoint scores" in said
    assert list(np.load(run / "eval" / "evaluations.npz")["timesteps"]) == [10]
    assert read_kept(run)["timesteps"] == 10
    assert json.loads((run / "manifest.json").read_text())["result"]["timesteps"] == 10


def test_stop_at_without_validation_is_refused_before_anything_runs(tmp_path, monkeypatch, capsys):
    from gymprecice.tools.cli import main

    monkeypatch.chdir(tmp_path)
    argv = ["train", "perpendicular-flap-fast", "--double", "--stop-at", "0.95"]
    assert main([*argv, "--no-validation", "--out", "run"]) == 2
    assert "--stop-at stops at a validation's score" in capsys.readouterr().err
    assert not (tmp_path / "run").exists()


def test_every_command_writes_a_duration_the_same_way() -> None:
    from gymprecice_lab.common.durations import duration_text

    assert duration_text(45.4) == "45 s"
    assert duration_text(545) == "9 min 05 s"
    assert duration_text(3725) == "1 h 02 min 05 s"
    assert duration_text(1090, to_the_minute=True) == "18 min"
    assert duration_text(3725, to_the_minute=True) == "1 h 02 min"
    assert duration_text(float("inf")) == "not reached"
    assert duration_text(None) == "an unknown time"


def test_a_rollout_on_the_validation_starts_runs_each_once_and_no_held_out_one(
    tmp_path, monkeypatch
):
    """``--validation-starts``: a model or a law looked at where models are chosen, over
    episodes as long as the evaluation's; the manifest says which starts it ran. About
    10 s on the test double."""
    from gymprecice.tools.cli import main

    monkeypatch.chdir(tmp_path)
    argv = ["baseline", "jet-cylinder-fast", "--double", "--episode-time", "0.2"]
    assert main([*argv, "--validation-starts", "--out", "run"]) == 0
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    labels = [episode["start_label"] for episode in summary["episodes"]]
    assert labels == ["t = 4.74 s", "t = 4.9 s"]
    settings = json.loads((tmp_path / "run" / "manifest.json").read_text())["settings"]
    assert settings["starts"] == "validation" and settings["held_out_starts"] is None
    assert not set(labels) & {"t = 4.82 s", "t = 4.98 s"}  # the held-out starts


def test_validation_time_sets_the_validation_episodes_and_a_resume_over_others_starts_afresh(
    tmp_path, monkeypatch, capsys
):
    """``--validation-time``: the validation episodes last that long (here 0.3 s against
    the training's 0.1 s and the default's settle time plus 0.1 s); the kept model's
    record says so. A run resumed over another length does not compare its scores with
    the earlier ones: it validates its checkpoint again. About 30 s on the test double."""
    from gymprecice.tools.cli import main

    monkeypatch.chdir(tmp_path)
    (tmp_path / "sac.yml").write_text(
        "gymprecice/JetCylinderFast-v0:\n  learning_starts: 4\n  batch_size: 8\n  net: [16, 16]\n"
    )
    argv = [
        *("train", "jet-cylinder-fast", "--double", "--episode-time", "0.1"),
        *("--algo", "sac", "--hyperparams", "sac.yml", "--checkpoint-every", "8"),
        *("--vec-env", "dummy", "--no-progress-bar", "--out", "run"),
    ]
    assert main([*argv, "--timesteps", "8", "--validation-time", "0.3"]) == 0
    run = tmp_path / "run"
    assert read_kept(run)["episode_time"] == pytest.approx(0.3)
    assert list(np.load(run / "eval" / "evaluations.npz")["timesteps"]) == [8]
    assert main([*argv, "--timesteps", "16", "--validation-time", "0.2"]) == 0
    assert read_kept(run)["episode_time"] == pytest.approx(0.2)
    # the checkpoint resumed from is validated again over the new length, then step 16
    assert list(np.load(run / "eval" / "evaluations.npz")["timesteps"]) == [8, 16]
