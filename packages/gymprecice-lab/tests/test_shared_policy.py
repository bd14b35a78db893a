"""``gymprecice train --shared-policy``: one policy that the two flaps' agents share.

Runs the lab's commands as a user does, on the two flaps' test double (four
participants: the controller, the double's fluid and two scripted flaps), and checks
what makes the policy shared: it takes one agent's row, each env step is one learner
step per agent, and evaluation runs it on both rows of the joint env.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

TRAIN = [
    "train",
    "two-flaps-fast",
    "--double",
    "--shared-policy",
    "--algo",
    "ppo",
    "--n-steps",
    "30",
    "--batch-size",
    "30",
    "--n-epochs",
    "1",
    "--net",
    "8,8",
    "--timesteps",
    "120",
    "--no-progress-bar",
    "--out",
    "train",
]


def _cli(cwd: Path, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "gymprecice", *args],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=300,
    )


@pytest.mark.slow
def test_a_shared_policy_trains_on_each_agents_row_and_evaluates_on_both(
    tmp_path: Path,
) -> None:
    trained = _cli(tmp_path, *TRAIN)
    assert trained.returncode == 0, trained.stderr
    assert "one policy shared by 2 agents (upstream, downstream" in trained.stdout
    # 120 learner steps are 60 env steps: two episodes of 30 actions, two agents each
    assert "gymprecice train: 120 steps" in trained.stdout
    assert json.loads((tmp_path / "train" / "hyperparams.json").read_text())["shared_policy"]
    monitor = (tmp_path / "train" / "monitor" / "env_0.monitor.csv").read_text().splitlines()
    assert len(monitor) - 2 == 2  # the header lines, then one row per env episode

    # the policy is one agent's; given the joint observation it acts for both rows
    import numpy as np
    from stable_baselines3 import PPO

    model = PPO.load(tmp_path / "train" / "model.zip", device="cpu")
    assert model.observation_space.shape == (9,) and model.action_space.shape == (1,)
    assert model.predict(np.zeros((2, 9), np.float32), deterministic=True)[0].shape == (2, 1)

    evaluated = _cli(
        tmp_path, "evaluate", "two-flaps-fast", "--double", "--policy", "train", "--out", "ev"
    )
    assert evaluated.returncode == 0, evaluated.stderr
    episodes = json.loads((tmp_path / "ev" / "summary.json").read_text())["episodes"]
    assert [e["steps"] for e in episodes] == [30] * len(episodes) and episodes


def test_shared_policy_needs_a_card_that_names_the_agents(tmp_path: Path) -> None:
    refused = _cli(tmp_path, "train", "quickstart", "--double", "--shared-policy", "--out", "train")
    assert refused.returncode != 0
    assert "--shared-policy" in refused.stderr and "EnvCard(agents=...)" in refused.stderr
    assert not (tmp_path / "train" / "model.zip").exists()


def test_a_hyperparameter_file_may_ask_for_it_but_only_as_true_or_false(tmp_path: Path) -> None:
    (tmp_path / "hp.yml").write_text("shared_policy: sometimes\n")
    refused = _cli(
        tmp_path,
        "train",
        "two-flaps-fast",
        "--double",
        "--hyperparams",
        "hp.yml",
        "--out",
        "train",
    )
    assert refused.returncode != 0
    assert "shared_policy is true or false" in refused.stderr


def test_the_episode_time_of_the_two_flaps_is_set_from_the_command_line(tmp_path: Path) -> None:
    ran = _cli(
        tmp_path, "baseline", "two-flaps-fast", "--double", "--episode-time", "0.5", "--out", "b"
    )
    assert ran.returncode == 0, ran.stderr
    episodes = json.loads((tmp_path / "b" / "summary.json").read_text())["episodes"]
    assert [e["steps"] for e in episodes] == [5]  # 0.5 s of actions of 0.1 s
