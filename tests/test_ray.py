"""The Ray backend on a real multi-node Ray cluster on this machine.

One cluster for the module: a head (where the test driver runs; no env slot) and two
worker nodes with one ``env`` slot each, so the two envs of a test land on two different,
remote nodes. Every case runs real envs (:class:`gymprecice.testing.chaos.CylinderEnv`:
Adapter, coupling worker, preCICE double, solver process) and checks the local pool's
promises on the Ray backend:

* envs spread over nodes (asserted through their node ids), logs back on the driver;
* a node lost mid-rollout costs its env one failure: it respawns on another node, the
  other env's rollout goes on, and no process of the lost env survives;
* the chaos faults of ``tests/test_chaos.py`` (solver kill -9, SIGSTOP, exit 1; the env's
  worker killed or stopped) on a remote node end as the local pool's do;
* Stable-Baselines3's PPO trains on the Ray backend.
"""

from __future__ import annotations

import functools
import logging
import sys
import time

import numpy as np
import pytest

ray = pytest.importorskip("ray", reason="the Ray backend needs gymprecice-core[ray]")
pytestmark = pytest.mark.skipif(
    not sys.platform.startswith("linux"), reason="process checks read /proc"
)

from ray.cluster_utils import Cluster  # noqa: E402

from gymprecice.testing.chaos import CylinderEnv, pid_alive  # noqa: E402
from gymprecice.vector import ResilientVectorEnv  # noqa: E402
from gymprecice.vector.ray import RayBackend, solver_cpus  # noqa: E402
from tests.test_chaos import (  # noqa: E402
    FAILED,
    MID_FAULTS,
    STEP_TIMEOUT_S,
    Chaos,
    fail_mid_episode,
    finish,
    watch,
)

SLOT = {"env": 1}
#: how long a removed node's processes may take to go (an upper bound, not a timing)
GONE_WITHIN_S = 60.0


@pytest.fixture(scope="module")
def cluster():
    cluster = Cluster(
        initialize_head=True,
        head_node_args={"num_cpus": 1, "include_dashboard": False},
    )
    for _ in range(2):
        cluster.add_node(num_cpus=1, resources=SLOT)
    cluster.wait_for_nodes()
    cluster.connect()
    yield cluster
    ray.shutdown()
    cluster.shutdown()


class RayChaos(Chaos):
    """The chaos set-up of ``tests/test_chaos.py``, its envs as Ray actors."""

    def make(self, n: int = 2) -> ResilientVectorEnv:
        fns = [
            functools.partial(CylinderEnv, str(self.case), i, run_root=str(self.runs))
            for i in range(n)
        ]
        self.venv = ResilientVectorEnv(
            fns,
            backend=RayBackend(resources=SLOT),
            step_timeout=STEP_TIMEOUT_S,
            reset_timeout=60,
            kill_grace=0.5,
            close_timeout=10,
            log_dir=self.tmp / "logs",
        )
        return self.venv


@pytest.fixture
def chaos(cluster, tmp_path, monkeypatch):
    monkeypatch.setenv("GYMPRECICE_DISABLE_PLUGINS", "1")  # forwarded to the actors
    state = RayChaos(tmp_path)
    yield state
    if state.venv is not None:
        state.venv.close()


def node_ids(venv: ResilientVectorEnv) -> list[str]:
    return [host.node_id for host in venv.pool.hosts]


def wait_gone(pids: set[int]) -> set[int]:
    deadline = time.monotonic() + GONE_WITHIN_S
    while time.monotonic() < deadline and any(pid_alive(p) for p in pids):
        time.sleep(0.2)
    return {p for p in pids if pid_alive(p)}


def test_envs_spread_over_nodes_and_logs_come_back(chaos, cluster):
    venv = chaos.make()
    head = cluster.head_node.node_id
    nodes = node_ids(venv)
    assert len(set(nodes)) == 2 and head not in nodes
    venv.reset(seed=0)
    for _ in range(3):
        obs, _, _, truncs, infos = venv.step(chaos.act())
        assert not truncs.any() and "failure" not in infos
    assert np.all(obs[:, 4] > 0)
    venv.close()
    for i in range(2):
        assert "worker pid" in (chaos.tmp / "logs" / f"env_{i}.log").read_text()


def test_a_lost_node_costs_its_env_one_failure_and_nothing_survives(chaos, cluster, caplog):
    caplog.set_level(logging.WARNING, logger="gymprecice.vector")
    venv = chaos.make()
    venv.reset(seed=0)
    venv.step(chaos.act())
    lost = node_ids(venv)[FAILED]
    watcher = watch(venv, FAILED)
    old = watcher.sample()
    assert old, "env 1 runs processes on its node"
    spare = cluster.add_node(num_cpus=1, resources=SLOT)  # room for the respawn
    cluster.wait_for_nodes()
    node = next(n for n in cluster.worker_nodes if n.node_id == lost)
    cluster.remove_node(node)
    obs, _, _, truncs, infos = venv.step(chaos.act())
    assert list(truncs) == [False, True]
    assert infos["failure"]["kind"][FAILED] == "crash"
    assert obs[0, 4] > 0 and obs[FAILED, 4] == 0.0  # env 0 went on; env 1 starts anew
    assert node_ids(venv)[FAILED] in {spare.node_id} and node_ids(venv)[FAILED] != lost
    for _ in range(2):
        obs, _, _, truncs, infos = venv.step(chaos.act())
        assert not truncs.any() and "failure" not in infos
    watcher.stop()
    assert not wait_gone(old), "processes of the lost node's env survived"
    assert len(venv.failures) == 1


@pytest.mark.parametrize(
    ("armed", "action", "kind", "type_suffix", "tail"),
    [case[1:] for case in MID_FAULTS if case[0] not in ("corrupt-output", "disk-full")],
    ids=[case[0] for case in MID_FAULTS if case[0] not in ("corrupt-output", "disk-full")],
)
def test_fault_mid_episode_on_a_remote_node(
    chaos, cluster, caplog, armed, action, kind, type_suffix, tail
):
    caplog.set_level(logging.WARNING, logger="gymprecice.vector")
    venv = chaos.make()
    assert cluster.head_node.node_id not in node_ids(venv)
    watcher = watch(venv, FAILED)
    fail_mid_episode(chaos, venv, armed, action, kind, type_suffix, tail)
    finish(chaos, watcher, caplog)


def test_sb3_ppo_trains_on_the_ray_backend(chaos):
    pytest.importorskip("stable_baselines3")
    from stable_baselines3 import PPO

    from gymprecice.learners.sb3 import ResilientSubprocVecEnv

    fns = [
        functools.partial(CylinderEnv, str(chaos.case), i, run_root=str(chaos.runs))
        for i in range(2)
    ]
    venv = ResilientSubprocVecEnv(
        fns, backend=RayBackend(resources=SLOT), log_dir=chaos.tmp / "logs", reset_timeout=60
    )
    try:
        model = PPO("MlpPolicy", venv, n_steps=8, batch_size=16, n_epochs=1, seed=0)
        model.learn(total_timesteps=32)
        assert model.num_timesteps >= 32
        assert venv.telemetry.steps >= 32 and not venv.failures
    finally:
        venv.close()


def test_an_env_asks_for_the_cpus_of_its_solvers(tmp_path):
    def fn():
        raise AssertionError("not called")

    fn.num_cpus = 4  # type: ignore[attr-defined]
    assert solver_cpus(fn) == 4
    assert solver_cpus(functools.partial(CylinderEnv, str(tmp_path), 0)) is None
