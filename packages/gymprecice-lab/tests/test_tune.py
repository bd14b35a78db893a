"""``gymprecice tune``: a search on the test double, killed and resumed, and its refusals.

Trials are ``gymprecice train`` runs of the quickstart on the test double with a tiny
network, so a trial costs seconds; the search space is cut to one or two parameters
(``--params``) so that the tests exercise the machinery, not the optimiser.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

FIXED = "gymprecice/Quickstart-v0:\n  net: [16, 16]\n  batch_size: 8\n  torch_threads: 1\n"
BASE = [
    "tune",
    "quickstart",
    "--double",
    "--episode-time",
    "0.1",
    "--timesteps",
    "16",
    "--validate-every",
    "8",
    "--hyperparams",
    "fixed.yml",
    "--no-progress-bar",
]
COMMON = [*BASE, "--algo", "sac", "--params", "learning_rate,gamma", "--out", "tune"]


def _cli(cwd: Path, *args: str, timeout: float = 600) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "gymprecice", *args],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=timeout,
    )


@pytest.mark.slow
def test_a_search_killed_mid_trial_resumes_and_loses_no_trial(tmp_path):
    """SIGKILL of the search while its first trial trains: the training gets SIGTERM and
    saves; the same command fails that trial, queues it again with its hyperparameters,
    resumes its training from the checkpoint and finishes the study. About a minute."""
    (tmp_path / "fixed.yml").write_text(FIXED)
    argv = [sys.executable, "-m", "gymprecice", *COMMON, "--trials", "1"]
    search = subprocess.Popen(argv, cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    checkpoint = tmp_path / "tune" / "trials" / "0" / "train" / "checkpoints"
    deadline = time.monotonic() + 300
    while not list(checkpoint.glob("sac_8_steps.zip")) and time.monotonic() < deadline:
        assert search.poll() is None, search.stdout.read().decode()
        time.sleep(0.2)
    assert list(checkpoint.glob("sac_8_steps.zip")), "the first trial never checkpointed"
    os.kill(search.pid, signal.SIGKILL)
    search.wait()
    log = tmp_path / "tune" / "trials" / "0" / "train.log"
    deadline = time.monotonic() + 180  # the orphaned training saves and stops on SIGTERM
    while "interrupted (SIGTERM)" not in log.read_text() and time.monotonic() < deadline:
        time.sleep(0.2)
    assert "interrupted (SIGTERM)" in log.read_text()

    done = _cli(tmp_path, *COMMON, "--trials", "1")
    assert done.returncode == 0, done.stdout + done.stderr
    assert "best trial" in done.stdout
    assert "resuming from" in log.read_text()  # the retried trial continued its training
    summary = json.loads((tmp_path / "tune" / "tune.json").read_text())
    assert summary["trials"] == {"complete": 1, "pruned": 0, "failed": 0}
    assert summary["best_trial"] == 1  # the retry of trial 0, which the kill left running
    # what the search cost: the killed trial up to when the resumed search found it dead,
    # and its retry
    assert set(summary["trial_seconds"]) == {"0", "1"}
    assert all(seconds > 0 for seconds in summary["trial_seconds"].values())
    best = (tmp_path / "tune" / "best_hyperparams.yml").read_text()
    assert "gymprecice/Quickstart-v0:" in best and "learning_rate" in best
    # the file is one train --hyperparams reads
    trained = _cli(
        tmp_path,
        "train",
        "quickstart",
        "--double",
        "--episode-time",
        "0.1",
        "--algo",
        "sac",
        "--hyperparams",
        "tune/best_hyperparams.yml",
        "--timesteps",
        "4",
        "--no-validation",
        "--no-progress-bar",
        "--out",
        "best",
    )
    assert trained.returncode == 0, trained.stderr
    assert (tmp_path / "tune" / "history.png").is_file()


def test_bad_input_gets_one_line_and_leaves_nothing(tmp_path):
    (tmp_path / "fixed.yml").write_text(FIXED)
    unknown = _cli(tmp_path, *BASE, "--params", "learning_rat", "--out", "a", timeout=120)
    assert unknown.returncode == 2
    assert "no such parameter" in unknown.stderr and "learning_rate" in unknown.stderr
    assert not (tmp_path / "a").exists()
    storage = _cli(tmp_path, *COMMON, "--storage", "nosuchdb://x/y", timeout=120)
    assert storage.returncode == 2 and "--storage nosuchdb://x/y: cannot open it" in storage.stderr
    assert not (tmp_path / "tune").exists()
    algo = _cli(tmp_path, *BASE, "--algo", "dqn", "--out", "b", timeout=120)
    assert algo.returncode == 2 and not (tmp_path / "b").exists()


def test_a_study_of_another_env_is_refused(tmp_path):
    from gymprecice_lab.training.tune import TuneError, open_study

    url = f"sqlite:///{tmp_path / 'study.db'}"
    settings = {"env_id": "a/A-v0", "algo": "sac", "timesteps": 16, "n_envs": 1, "double": True}
    open_study(url, "s", settings, seed=0)
    open_study(url, "s", settings, seed=0)  # the same settings: resumed
    with pytest.raises(TuneError, match="env_id='a/A-v0'"):
        open_study(url, "s", {**settings, "env_id": "b/B-v0"}, seed=0)


def test_the_search_space_keeps_unsearched_parameters_at_their_defaults():
    import optuna

    from gymprecice_lab.training.tune_spaces import DEFAULTS, sample

    study = optuna.create_study()
    trial = study.ask()
    params = sample(trial, "sac", 1000, 2, {"net": [16, 16]}, ["learning_rate"])
    assert set(trial.params) == {"learning_rate"}
    assert params["gamma"] == DEFAULTS["sac"]["gamma"] and params["net"] == [16, 16]
    assert params["learning_starts"] == 20  # a fraction of the trial's budget
    ppo = sample(study.ask(), "ppo", 1000, 2, {}, None)
    assert ppo["batch_size"] <= ppo["n_steps"] * 2


def test_workers_and_resumed_searches_do_not_propose_the_same_first_trials(tmp_path):
    """Two ``--n-jobs`` workers opening a study at once, and a search resumed with the
    same command, get samplers of their own: seeded alike, each proposed the same first
    trial (a wasted trial per worker)."""
    from gymprecice_lab.training.tune import open_study

    url = f"sqlite:///{tmp_path / 'study.db'}"
    settings = {"env_id": "a/A-v0", "algo": "sac", "timesteps": 16, "n_envs": 1, "double": True}

    def first_proposal(worker: int) -> float:
        study = open_study(url, "s", settings, seed=0, worker=worker)
        trial = study.ask()
        value = trial.suggest_float("learning_rate", 1e-4, 3e-3, log=True)
        study.tell(trial, 0.0)
        return value

    proposals = [first_proposal(0), first_proposal(1), first_proposal(0)]
    assert len(set(proposals)) == 3, proposals
    again = tmp_path / "again"
    again.mkdir()
    url = f"sqlite:///{again / 'study.db'}"
    assert first_proposal(0) == proposals[0]  # the same command on a new study: reproducible


@pytest.mark.slow
@pytest.mark.timeout(600)
def test_with_ray_the_workers_run_trials_of_one_study_on_the_cluster(ray_cluster, tmp_path):
    """``--ray ADDRESS --n-jobs 2``: each worker is a Ray task on a worker node (the head
    has no CPU), its trials train there, the study holds both, and the report is written
    here from the study."""
    import optuna

    (tmp_path / "fixed.yml").write_text(FIXED)
    run = _cli(tmp_path, *COMMON, "--trials", "2", "--n-jobs", "2", "--ray", ray_cluster.address)
    assert run.returncode == 0, run.stdout + run.stderr
    assert f"(2 at once on the Ray cluster at {ray_cluster.address})" in run.stdout
    assert run.stdout.count("exit status 0") == 2
    study = optuna.load_study(
        study_name="quickstart-sac", storage=f"sqlite:///{tmp_path / 'tune' / 'study.db'}"
    )
    trials = study.get_trials(deepcopy=False)
    assert [t.state.name for t in trials] == ["COMPLETE", "COMPLETE"]
    workers = {node.node_id for node in ray_cluster.worker_nodes}
    assert {t.user_attrs["ray_node"] for t in trials} <= workers
    summary = json.loads((tmp_path / "tune" / "tune.json").read_text())
    assert summary["trials"]["complete"] == 2
    assert (tmp_path / "tune" / "best_hyperparams.yml").is_file()


def test_with_ray_a_cluster_that_does_not_answer_is_refused_and_leaves_nothing(tmp_path):
    pytest.importorskip("ray", reason="tune --ray needs gymprecice-core[ray]")
    (tmp_path / "fixed.yml").write_text(FIXED)
    run = _cli(tmp_path, *COMMON, "--n-jobs", "2", "--ray", "127.0.0.1:1")
    assert run.returncode == 2
    assert run.stderr.startswith("gymprecice tune: --ray 127.0.0.1:1: no Ray cluster answers")
    assert len(run.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "tune").exists()
