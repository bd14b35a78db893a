"""Model-ensemble PPO (:mod:`gymprecice_lab.model_based`) trained on a tutorial env, as a
user runs it: ``gymprecice train`` on the jet cylinder's test double."""

from __future__ import annotations

import csv
import json
import shlex

import numpy as np

# -- as a user runs it ---------------------------------------------------------------------


def test_train_with_a_model_ensemble_on_the_double_resumes_with_its_transitions(
    tmp_path, gymprecice_cli
):
    (tmp_path / "me.yml").write_text(
        "model_ensemble:\n  members: 2\n  updates: 2\n  hidden: [16]\n  epochs: 3\n  quorum: 0\n"
    )
    # 24-action episodes: the first training's 24 steps per env are one episode, so each
    # env starts its solvers twice, not four times (the transitions do not care)
    train = shlex.split(
        "train jet-cylinder-fast --double --n-envs 2 --n-steps 8 --batch-size 8 --n-epochs 1 "
        "--episode-time 0.6 --net 16,16 --normalize --hyperparams me.yml --no-progress-bar "
        "--out run"
    )
    gymprecice_cli(tmp_path, *train, "--timesteps", "48")
    run = tmp_path / "run"
    kept = run / "model_ensemble" / "transitions.npz"
    with np.load(kept) as data:
        assert len(data["actions"]) == 48 and data["obs"].shape[1] == 151
    assert json.loads((run / "hyperparams.json").read_text())["model_ensemble"]["members"] == 2
    # SB3 logs before each update: the third rollout's line has the second's model updates
    rows = list(csv.DictReader((run / "progress.csv").open()))
    assert float(rows[-1]["model/updates"]) == 2

    out = gymprecice_cli(tmp_path, *train, "--timesteps", "64")
    assert "model ensemble: 48 CFD transitions kept" in out
    with np.load(kept) as data:
        assert len(data["actions"]) == 64
    assert (run / "checkpoints" / "ppo_64_steps.zip").is_file()

    gymprecice_cli(tmp_path, *train, "--timesteps", "16", "--fresh")
    with np.load(kept) as data:
        assert len(data["actions"]) == 16  # --fresh dropped the earlier run's flow
