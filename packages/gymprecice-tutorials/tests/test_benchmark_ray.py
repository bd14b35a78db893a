"""``gymprecice benchmark --ray`` on a real Ray cluster on this machine (the test double's
flow): every seed trains at once with its envs as Ray actors on the cluster's nodes, and the
table comes out as it does on one machine; a cluster that does not answer is refused before
anything trains."""

from __future__ import annotations

import json

import pytest

ray = pytest.importorskip("ray", reason="benchmark --ray needs gymprecice-core[ray]")

from ray.cluster_utils import Cluster  # noqa: E402

from gymprecice.cli import main  # noqa: E402

#: the benchmark of test_benchmark.py, without baselines (they run on this machine as there)
TINY = [
    "jet-cylinder-fast",
    "--double",
    "--seeds",
    "2",
    "--algo",
    "ppo",
    "--timesteps",
    "16",
    "--episode-time",
    "0.1",
    "--eval-time",
    "0.15",
    "--train-args",
    "--n-steps 8 --batch-size 8 --net 8,8",
    "--no-baselines",
    "--bootstrap-reps",
    "200",
]


@pytest.fixture(scope="module")
def cluster():
    """A head with no CPU for envs and two worker nodes: every env actor lands on a worker."""
    cluster = Cluster(
        initialize_head=True, head_node_args={"num_cpus": 0, "include_dashboard": False}
    )
    for _ in range(2):
        cluster.add_node(num_cpus=2)
    cluster.wait_for_nodes()
    yield cluster
    if ray.is_initialized():
        ray.shutdown()
    cluster.shutdown()


@pytest.mark.timeout(600)
def test_every_seed_trains_at_once_with_its_envs_on_the_cluster(
    cluster, tmp_path, capsys, monkeypatch
):
    out, nodes = tmp_path / "bench", tmp_path / "nodes"
    monkeypatch.setenv("GYMPRECICE_NODE_DIR", str(nodes))  # where the env actors work
    assert main(["benchmark", *TINY, "--ray", cluster.address, "--out", str(out)]) == 0
    said = capsys.readouterr().out
    assert (
        f"training 2 seed(s) at once, their envs as Ray actors on the cluster at {cluster.address}"
        in said
    )
    for seed in range(2):
        assert (out / "train" / "ppo" / f"seed_{seed}" / "model.zip").is_file()
        assert (out / "eval" / "ppo" / f"seed_{seed}" / "summary.json").is_file()
    rows = json.loads((out / "results.json").read_text())["controllers"]
    assert [c["label"] for c in rows] == ["PPO"]

    # one env per seed, each an actor that worked in its node directory: on a worker node,
    # as the head has no CPU to give
    actors = sorted(p.name.split("-")[0] for p in (nodes / "gymprecice-ray").iterdir())
    assert actors == ["env_0", "env_0"]


def test_a_cluster_that_does_not_answer_is_refused_before_training(tmp_path, capsys):
    out = tmp_path / "bench"
    with pytest.raises(SystemExit) as exc:
        main(["benchmark", *TINY, "--ray", "127.0.0.1:1", "--out", str(out)])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "--ray 127.0.0.1:1: no Ray cluster answers there" in err
    assert not (out / "train").exists()
