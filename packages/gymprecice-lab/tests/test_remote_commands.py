"""``gymprecice`` commands as Ray tasks: what is shipped, what comes back, and that a failed
or interrupted command is reported and leaves nothing running. (The benchmark's own use,
on the test double, is in test_benchmark.py.)"""

from __future__ import annotations

import json
import os
import signal
import threading
import time
from pathlib import Path

import pytest

from gymprecice_lab.benchmarking.remote_commands import (
    RemoteCommand,
    RemoteCommandError,
    check_fits,
    pack,
    run_commands,
    unpack,
)


def _tree(root: Path) -> list[str]:
    return sorted(str(p.relative_to(root)) for p in root.rglob("*") if p.is_file())


def test_a_training_directory_ships_its_top_level_files_and_an_output_comes_back_without_runs(
    tmp_path,
) -> None:
    train = tmp_path / "train"
    for name in ("model.zip", "model_vecnormalize.pkl", "manifest.json"):
        (train / name).parent.mkdir(parents=True, exist_ok=True)
        (train / name).write_text(name)
    for deep in ("checkpoints/ppo_800_steps.zip", "envs/env_0/fluid/0.1/U"):
        (train / deep).parent.mkdir(parents=True, exist_ok=True)
        (train / deep).write_text("big")
    unpack(pack(train, top_level_only=True), tmp_path / "shipped")
    assert _tree(tmp_path / "shipped") == ["manifest.json", "model.zip", "model_vecnormalize.pkl"]

    out = tmp_path / "out"
    for name in ("summary.json", "envs/env_0/fluid/log.pimpleFoam", "envs/env_0/fluid/0.1/U"):
        (out / name).parent.mkdir(parents=True, exist_ok=True)
        (out / name).write_text(name)
    (out / "envs/env_0/worker.log").write_text("log")
    unpack(pack(out, skip_runs=True), tmp_path / "back")
    assert _tree(tmp_path / "back") == [
        "envs/env_0/fluid/log.pimpleFoam",
        "envs/env_0/worker.log",
        "summary.json",
    ]


def test_a_training_run_shipped_to_a_node_keeps_its_kept_model(tmp_path) -> None:
    """``evaluate --model kept`` on the node must take the model training kept, which its
    record in ``eval/best.json`` names: shipped without it, the node took the final model
    and the benchmark's kept-model evaluation on a cluster was the final model's."""
    from gymprecice_lab.benchmarking.remote_commands import _input_archive
    from gymprecice_lab.common.kept_model import choose_model

    train = tmp_path / "seed_0"
    (train / "eval").mkdir(parents=True)
    (train / "model.zip").write_text("final")
    (train / "best_model.zip").write_text("kept")
    (train / "eval" / "best.json").write_text(json.dumps({"timesteps": 16, "mean_return": 0.5}))
    (train / "eval" / "env_0.monitor.csv").write_text("validation episodes")
    name, is_dir, blob = _input_archive("--policy", train)
    assert (name, is_dir) == ("seed_0", True)
    unpack(blob, tmp_path / "node" / name)
    shipped = tmp_path / "node" / name
    assert _tree(shipped) == ["best_model.zip", "eval/best.json", "model.zip"]
    assert choose_model(shipped, "kept")[0] == shipped / "best_model.zip"
    assert choose_model(shipped, "final")[0] == shipped / "model.zip"


def test_a_command_no_node_can_hold_is_refused_with_the_fix() -> None:
    check_fits([("the sweep", 8)], 8)
    with pytest.raises(RemoteCommandError, match="the sweep needs 8 CPUs on one node, but the"):
        check_fits([("the sweep", 8)], 4)


def test_a_failed_command_is_reported_with_its_output_tail_after_the_others_ran(
    ray_cluster, tmp_path, monkeypatch
) -> None:
    monkeypatch.setenv("GYMPRECICE_NODE_DIR", str(tmp_path / "nodes"))
    good = RemoteCommand(
        ["baseline", "jet-cylinder-fast", "--double", "--episode-time", "0.05"],
        tmp_path / "good",
        "an uncontrolled rollout",
    )
    bad = RemoteCommand(["evaluate", "no-such-env"], tmp_path / "bad", "evaluating nothing")
    with pytest.raises(RemoteCommandError) as exc:
        run_commands([bad, good], ray_cluster.address)
    message = str(exc.value)
    assert "evaluating nothing: exit status 2 on" in message
    assert "no-such-env" in message  # the command's own error, from its output's tail
    assert "uncontrolled rollout" not in message
    assert json.loads((tmp_path / "good" / "remote.json").read_text())["status"] == 0
    assert (tmp_path / "good" / "summary.json").is_file()
    assert not list((tmp_path / "nodes").glob("gymprecice-command-*"))


def _running_under(directory: Path) -> dict[int, str]:
    """Processes whose command line names ``directory`` (the commands' scratch): pid,
    command line."""
    found = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                cmdline = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode()
            except OSError:
                continue
            if str(directory) in cmdline:
                found[int(entry.name)] = cmdline
    return found


@pytest.mark.timeout(240)
def test_sigterm_on_the_driver_cancels_the_tasks_and_their_commands_and_solvers_stop(
    ray_cluster, tmp_path, monkeypatch
) -> None:
    nodes = tmp_path / "nodes"
    monkeypatch.setenv("GYMPRECICE_NODE_DIR", str(nodes))
    # a long uncontrolled episode on the test double: a command with a solver partner
    long = RemoteCommand(
        ["baseline", "jet-cylinder-fast", "--double", "--episode-time", "1000"],
        tmp_path / "long",
        "a long rollout",
    )

    seen: list[int] = []

    def stop_when_running() -> None:  # SIGTERM once the command's solver partner runs
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and not seen:
            running = _running_under(nodes).items()
            seen.extend(p for p, c in running if "gymprecice.testing.partner" in c)
            time.sleep(0.5)
        os.kill(os.getpid(), signal.SIGTERM)

    threading.Thread(target=stop_when_running, daemon=True).start()
    from gymprecice_lab.training.callbacks import Interrupted

    with pytest.raises(Interrupted):
        run_commands([long], ray_cluster.address)
    assert seen, "the command's solver never started on the node"
    deadline = time.monotonic() + 60
    while _running_under(nodes) and time.monotonic() < deadline:
        time.sleep(0.5)
    assert _running_under(nodes) == {}
