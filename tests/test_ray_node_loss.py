"""A Ray node lost during ``gymprecice train --ray`` and ``gymprecice benchmark --ray``.

One real cluster on this machine for the module (:class:`ray.cluster_utils.Cluster`): a
head of one CPU and a worker node of one CPU, so that the two envs of a command (two
envs of one training, or one env of each of two seeds) land one on each node. Each command
runs as a driver of its own (``python -m gymprecice ... --ray ADDRESS``), as a user runs
it; the test removes the worker node while the envs step, then adds a node in its place
(a replacement node joining, as a cluster manager brings one): the lost env's actor waits
for room, starts on the new node, and the command finishes and reports the restart.

The fixture is named ``ray_cluster`` so that the suite's scheduler keeps these tests on
the worker that runs the other Ray tests (conftest.py: two clusters would compete for the
same ports and cores). Nothing of the cluster outlives the module.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

ray = pytest.importorskip("ray", reason="--ray needs gymprecice-core[ray]")
pytest.importorskip("stable_baselines3", reason="gymprecice train needs the lab's extras")
pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(not sys.platform.startswith("linux"), reason="Ray clusters on Linux"),
]

from ray.cluster_utils import Cluster  # noqa: E402

#: the commands' small PPO on the test double: 8-step rollouts, tiny nets, no validation
TRAIN_FLAGS = ["--n-steps", "8", "--batch-size", "8", "--net", "8,8", "--no-validation"]
#: an upper bound for one command (a lost node's env restarts once, on a new node)
COMMAND_LIMIT_S = 240.0


@pytest.fixture(scope="module")
def ray_cluster():
    cluster = Cluster(
        initialize_head=True, head_node_args={"num_cpus": 1, "include_dashboard": False}
    )
    cluster.add_node(num_cpus=1)
    cluster.wait_for_nodes()
    yield cluster
    cluster.shutdown()
    assert not cluster.head_node and not cluster.worker_nodes


def _worker(cluster: Cluster):
    (node,) = cluster.worker_nodes
    return node


def _rows(monitor: Path) -> int:
    """Episodes a Monitor file records (after its two header lines)."""
    try:
        return max(0, len(monitor.read_text().splitlines()) - 2)
    except OSError:
        return 0


def _start(tmp_path: Path, argv: list[str]) -> tuple[subprocess.Popen, Path]:
    """``python -m gymprecice ARGV`` as a driver of its own, its output in a file."""
    log = tmp_path / "command.log"
    env = {**os.environ, "GYMPRECICE_NODE_DIR": str(tmp_path / "nodes")}
    with open(log, "wb") as sink:
        process = subprocess.Popen(
            [sys.executable, "-m", "gymprecice", *argv],
            cwd=tmp_path,
            env=env,
            stdin=subprocess.DEVNULL,
            stdout=sink,
            stderr=subprocess.STDOUT,
        )
    return process, log


def _lose_the_worker_node_once(cluster, process, log, monitors: list[Path]) -> None:
    """Once every env in ``monitors`` finished an episode, remove the worker node (an env
    of the command runs there) and add a node of one CPU in its place."""
    deadline = time.monotonic() + COMMAND_LIMIT_S
    while not all(_rows(m) >= 1 for m in monitors):
        assert process.poll() is None, log.read_text()[-3000:]
        assert time.monotonic() < deadline, "the envs did not step: " + log.read_text()[-3000:]
        time.sleep(0.5)
    cluster.remove_node(_worker(cluster), allow_graceful=False)
    cluster.add_node(num_cpus=1)


def _finish(process: subprocess.Popen, log: Path) -> str:
    try:
        status = process.wait(COMMAND_LIMIT_S)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait()
        pytest.fail("the command did not finish: " + log.read_text()[-3000:])
    said = log.read_text()
    assert status == 0, said[-3000:]
    return said


def _env_failures(run: Path) -> list[dict]:
    path = run / "workers" / "failures.jsonl"
    return [json.loads(line) for line in path.read_text().splitlines()] if path.exists() else []


def test_a_node_lost_during_vectorised_training_restarts_its_env_elsewhere(ray_cluster, tmp_path):
    """Two envs as actors, one on each node; the worker node is lost mid-training. Its env
    is re-created on the node that joins in its place (one worker restart, one failure of
    kind crash on a *lost node*), the training finishes to its steps and the run's
    ``workers/failures.jsonl`` records the restart.

    Cost: about 60 s (a training of 48 steps on two envs; the node's loss takes Ray about
    15 s to see, the new node and the env's restart about 15 s more).
    """
    out = tmp_path / "train"
    argv = [
        *("train", "quickstart", "--double", "--episode-time", "0.1", "--n-envs", "2"),
        *("--ray", ray_cluster.address, "--timesteps", "48", "--checkpoint-every", "16"),
        *(*TRAIN_FLAGS, "--no-progress-bar", "--out", str(out)),
    ]
    process, log = _start(tmp_path, argv)
    monitors = [out / "monitor" / f"env_{i}.monitor.csv" for i in range(2)]
    _lose_the_worker_node_once(ray_cluster, process, log, monitors)
    said = _finish(process, log)

    assert "1 failures, 0 divergences, 1 worker restarts" in said
    (failure,) = _env_failures(out)
    assert failure["kind"] == "crash" and "on lost node" in failure["message"]
    result = json.loads((out / "manifest.json").read_text())["result"]
    assert result["timesteps"] >= 48 and not result["interrupted"]


def test_a_node_lost_while_a_benchmark_seed_trains_is_reported_in_its_results(
    ray_cluster, tmp_path
):
    """Two seeds train at once, one env each, one on each node; the worker node is lost
    while they train. The seed whose env ran there goes on with its env re-created on the
    node that joins in its place; both seeds finish, are evaluated on the cluster, and the
    results (results.json and the note under results.md's tables) say which seed restarted
    its env, once.

    Cost: about 100 s (two trainings of 32 steps, the restart as above, two evaluations
    as Ray tasks of a process each).
    """
    out = tmp_path / "bench"
    argv = [
        *("benchmark", "quickstart", "--double", "--seeds", "2", "--algo", "ppo"),
        *("--timesteps", "32", "--train-args", " ".join(TRAIN_FLAGS)),
        *("--episode-time", "0.1", "--eval-time", "0.05", "--no-baselines"),
        *("--bootstrap-reps", "50", "--ray", ray_cluster.address, "--out", str(out)),
    ]
    process, log = _start(tmp_path, argv)
    runs = [out / "train" / "ppo" / f"seed_{k}" for k in range(2)]
    _lose_the_worker_node_once(
        ray_cluster, process, log, [run / "monitor" / "env_0.monitor.csv" for run in runs]
    )
    said = _finish(process, log)

    restarted = [k for k, run in enumerate(runs) if _env_failures(run)]
    assert len(restarted) == 1, said[-3000:]
    (seed,) = restarted
    assert [f["kind"] for f in _env_failures(runs[seed])] == ["crash"]
    expected = {
        f"PPO seed {k}": {"env_restarts": int(k == seed), "training_reruns": 0} for k in range(2)
    }
    assert json.loads((out / "results.json").read_text())["restarts"] == expected
    (note,) = [
        line
        for line in (out / "results.md").read_text().splitlines()
        if line.startswith("Restarts while training, per seed")
    ]
    assert f"PPO seed {seed}: 1 env restart" in note
    assert f"PPO seed {1 - seed}: none" in note
    assert all((run / "model.zip").is_file() for run in runs)
