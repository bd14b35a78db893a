"""The lab serves any env from its card: metrics, starts, solver checks, description.

Toy envs registered through the public hook stand for a user's own package: their episode
metrics, starts and solvers are none of the cylinders', and every command must say so.
"""

from __future__ import annotations

import csv
import json
import warnings
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

from gymprecice.plugin.card import EnvCard
from gymprecice.plugin.hookspecs import hookimpl
from gymprecice.plugin.manager import temporary_plugin
from gymprecice.plugin.registration import register_environments
from gymprecice.tools.cli import main
from gymprecice_lab.common.registered_env import find_lab_env

TRACKING = "labcard/Tracking-v0"  # objective and metrics of its own, held-out starts
SEEDED = "labcard/Seeded-v0"  # names starts in a property, but its card declares none
CLAIMED = "labcard/Claimed-v0"  # its card declares held-out starts the env does not name


class TrackingEnv(gym.Env):
    """Four actions an episode; ``err`` is one more than the action's size, ``temp`` a
    constant, ``extra`` a metric no card declares."""

    dt = 0.1

    def __init__(self, idx: int = 0, double: bool = False, **kwargs: Any) -> None:
        self.action_space = gym.spaces.Box(-2.0, 2.0, shape=(1,), dtype=np.float32)
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, shape=(1,), dtype=np.float32)
        self.steps = 0

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> Any:
        super().reset(seed=seed)
        self.steps = 0
        return np.zeros(1, dtype=np.float32), {"time": 0.0}

    def step(self, action: Any) -> Any:
        self.steps += 1
        err = 1.0 + float(np.abs(np.asarray(action)).mean())
        info = {
            "time": self.steps * self.dt,
            "metrics": {"err": err, "temp": 300.0, "extra": 2.0 * err},
        }
        return np.array([err], dtype=np.float32), -err, False, self.steps >= 4, info


class NamedStartsEnv(TrackingEnv):
    held_out_starts = ("warm", "cold")


class TogglePlugin:
    @hookimpl
    def gymprecice_register_environments(self, register):
        card = {
            "name": "tracking",
            "description": "hold a toy's error down",
            "objective": "err",
            "metrics": ("temp",),
            "held_out_starts": True,
            "double": True,
            "training_case": "seeded",
            "solver_checks": ("pyprecice", "dealii"),
            "solver_checks_with": {"solid=fenics": ("pyprecice", "fenics")},
        }
        register(TRACKING, f"{__name__}:NamedStartsEnv", card=card)
        register(SEEDED, f"{__name__}:NamedStartsEnv", card=EnvCard(name="seeded", double=True))
        register(
            CLAIMED,
            f"{__name__}:TrackingEnv",
            card=EnvCard(name="claimed", double=True, held_out_starts=True),
        )


@pytest.fixture(scope="module", autouse=True)
def toy_envs():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with temporary_plugin(TogglePlugin(), "labcard-toys"):
            register_environments()
    yield
    for env_id in (TRACKING, SEEDED, CLAIMED):
        gym.registry.pop(env_id, None)


def _status(argv: list[str]) -> int:
    try:
        return main(argv)
    except SystemExit as exc:
        return int(exc.code or 0)


# -- episode metrics: the Monitor's columns, TensorBoard's scalars -------------------------


def test_monitor_columns_are_the_cards_metrics(tmp_path: Path) -> None:
    from gymprecice_lab.common.wrapped_env import episode_keywords, make_env

    assert episode_keywords(TRACKING) == ("mean_err", "mean_temp", "action_rms")
    assert episode_keywords(SEEDED) == ("action_rms",)  # a card without metrics
    env = make_env(TRACKING, 0, {"double": True}, monitor_file=str(tmp_path / "env_0"))
    env.reset(seed=0)
    done = False
    while not done:
        *_, terminated, truncated, info = env.step(np.array([0.5], dtype=np.float32))
        done = terminated or truncated
    env.close()
    lines = (tmp_path / "env_0.monitor.csv").read_text().splitlines()
    assert lines[1] == "r,l,t,mean_err,mean_temp,action_rms", lines[1]
    (row,) = csv.DictReader(lines[1:])
    # the policy's 0.5 is 1.0 in the env's own units ([-2, 2]): err 2, the RMS 1
    assert float(row["mean_err"]) == pytest.approx(2.0)
    assert float(row["mean_temp"]) == pytest.approx(300.0)
    assert float(row["action_rms"]) == pytest.approx(1.0)
    # TensorBoard gets every metric the env reported, declared or not
    assert info["episode_metrics"]["mean_extra"] == pytest.approx(4.0)


def test_training_logs_each_envs_own_metrics() -> None:
    from gymprecice_lab.training.callbacks import EpisodeMetricsCallback

    recorded: dict[str, float] = {}
    logger = SimpleNamespace(record_mean=lambda key, value: recorded.setdefault(key, value))
    callback = EpisodeMetricsCallback()
    callback.model = SimpleNamespace(logger=logger)  # type: ignore[assignment]
    means = {"mean_err": 1.5, "mean_temp": float("nan"), "action_rms": 0.2}
    callback.locals = {"infos": [{"episode_metrics": means}, {}]}
    assert callback._on_step()
    assert recorded == {"env/mean_err": 1.5, "env/action_rms": 0.2}  # NaN: never reported


def test_evaluate_reports_the_objective_and_its_change(tmp_path: Path, capsys) -> None:
    base, run = tmp_path / "baseline", tmp_path / "open-loop"
    assert main(["baseline", "tracking", "--double", "--out", str(base)]) == 0
    argv = ["open-loop", "tracking", "--double", "--out", str(run), "--baseline", str(base)]
    assert main([*argv, "--amplitude", "0.5"]) == 0
    line = capsys.readouterr().out.strip().splitlines()[-1]
    assert "mean err " in line and "% against the baseline" in line and "mean temp" in line
    assert "Cd" not in line


# -- starts: the card's held_out_starts flag ------------------------------------------------


def _labels(out: Path) -> list[str]:
    summary = json.loads((out / "summary.json").read_text())
    return [e["start_label"] for e in summary["episodes"]]


def test_the_card_says_whether_the_env_has_held_out_starts(tmp_path: Path, capsys) -> None:
    assert (
        main(["baseline", "tracking", "--double", "--all-starts", "--out", str(tmp_path / "t")])
        == 0
    )
    assert _labels(tmp_path / "t") == ["warm", "cold"]
    # the same env class, its card declaring no held-out starts: seeds
    assert (
        main(["baseline", "seeded", "--double", "--all-starts", "--out", str(tmp_path / "s")]) == 0
    )
    assert _labels(tmp_path / "s") == [f"seed {k}" for k in range(5)]


def test_a_card_claiming_starts_the_env_does_not_name_is_refused(tmp_path: Path, capsys) -> None:
    out = tmp_path / "c"
    assert _status(["baseline", "claimed", "--double", "--all-starts", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "held_out_starts" in err[0] and "property" in err[0], err


def test_benchmark_says_what_its_starts_are(tmp_path: Path, capsys, monkeypatch) -> None:
    from gymprecice_lab import benchmark

    class Stop(Exception):
        pass

    def stop(*args: Any) -> None:
        raise Stop

    monkeypatch.setattr(benchmark, "_train_seeds", stop)
    for name, expected in (("seeded", "5 seeded start(s)"), ("tracking", "2 held-out start(s)")):
        with pytest.raises(Stop):
            main(["benchmark", name, "--double", "--seeds", "1", "--out", str(tmp_path / name)])
        said = capsys.readouterr().out
        assert f"evaluated from {expected}" in said, said
    assert "names seeded as its training case" in said  # the card's training_case


def test_results_name_the_env_and_its_starts(tmp_path: Path) -> None:
    from gymprecice_lab.benchmarking.tables import write_tables

    controllers = [
        {
            "label": "uncontrolled",
            "kind": "baseline",
            "runs": 1,
            "metrics": {
                "objective": {
                    s: {"value": 1.0, "low": 1.0, "high": 1.0, "runs": 1}
                    for s in ("mean", "median", "iqm")
                }
            },
        }
    ]
    write_tables(tmp_path, find_lab_env("seeded"), ["seed 0", "seed 1"], controllers)
    text = (tmp_path / "results.md").read_text()
    assert "2 seeded start(s)" in text and "held-out start(s)" not in text
    write_tables(tmp_path, find_lab_env("tracking"), ["warm", "cold"], controllers)
    text = (tmp_path / "results.md").read_text()
    assert "hold a toy's error down" in text and "2 held-out start(s)" in text


# -- solver checks that follow the env's keyword arguments ---------------------------------


def test_solver_checks_follow_the_env_kwargs() -> None:
    from gymprecice_lab.common.requirements import missing_requirements

    report = {
        "checks": [
            {"name": name, "ok": False, "required": False}
            for name in ("deal.II library", "dealii adapter", "FEniCS solver environment")
        ]
    }
    env = find_lab_env("tracking")
    names = [c["name"] for c in missing_requirements(report, env, {"double": False})]
    assert names == ["dealii adapter"]  # "dealii" matches it, not "deal.II library"
    names = [c["name"] for c in missing_requirements(report, env, {"solid": "fenics"})]
    assert names == ["FEniCS solver environment"]


# -- help texts ------------------------------------------------------------------------------


def test_help_speaks_of_the_env_not_the_cylinders(capsys) -> None:
    assert _status(["--help"]) == 0
    listing = capsys.readouterr().out
    assert "lift fed back on the jets" not in listing and "drag floor" not in listing
    for command in ("feedback", "time-to-floor"):
        assert _status([command, "--help"]) == 0
        text = " ".join(capsys.readouterr().out.split())
        assert "jets" not in text
        if command == "feedback":
            assert "feedback_law" in text and "feedback_signal" in text
        else:
            assert "'reference'" in text
