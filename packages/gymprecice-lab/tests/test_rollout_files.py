"""What the lab writes and draws for any registered env, not only the tutorials' cylinders:
``coefficients.csv`` only with the force coefficients an env reports, figures labelled with
the card's objective and action unit, and one description of the "uncontrolled" default
that says what ``baseline`` really runs."""

from __future__ import annotations

import csv
import io
import json
import re
from pathlib import Path
from typing import Any

import gymnasium as gym
import matplotlib.figure
import numpy as np
import pytest

import gymprecice.card
from gymprecice.plugin.card import EnvCard
from gymprecice.plugin.hookspecs import hookimpl
from gymprecice.plugin.manager import temporary_plugin
from gymprecice.plugin.registration import register_environments
from gymprecice.tools.cli import main
from gymprecice_lab.benchmarking.plots import plot_objective_per_start
from gymprecice_lab.common.registered_env import LabEnv, find_lab_env
from gymprecice_lab.rollouts.sweep import SweepResult, _figure

ROOT = Path(__file__).resolve().parents[3]
SHIFTED = "labfiles/Shifted-v0"
FORCES = "labfiles/Forces-v0"
#: what every description of the default "uncontrolled" says
UNCONTROLLED = "zero action clipped into the action box"


class ShiftedEnv(gym.Env):
    """Three actions an episode in a box that leaves zero out ([0.5, 2]): its clipped zero
    is 0.5, its middle 1.25. Its one metric, ``x``, is the action; no force coefficients."""

    def __init__(self, idx: int = 0, double: bool = False, **kwargs: Any) -> None:
        self.action_space = gym.spaces.Box(0.5, 2.0, shape=(1,), dtype=np.float32)
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, shape=(1,), dtype=np.float32)
        self.steps = 0

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> Any:
        super().reset(seed=seed)
        self.steps = 0
        return np.zeros(1, dtype=np.float32), {"time": 0.0}

    def step(self, action: Any) -> Any:
        self.steps += 1
        value = float(np.asarray(action).reshape(-1)[0])
        info = {"time": 0.1 * self.steps, "metrics": {"x": value}}
        return np.zeros(1, dtype=np.float32), -value, False, self.steps >= 3, info


class ForcesEnv(ShiftedEnv):
    """The same in [-1, 1], reporting a cylinder's ``Cd``/``Cl`` and two solver steps'
    ``(time, Cd, Cl)`` rows an action, as the cylinder tutorials do."""

    def __init__(self, idx: int = 0, double: bool = False, **kwargs: Any) -> None:
        super().__init__(idx, double, **kwargs)
        self.action_space = gym.spaces.Box(-1.0, 1.0, shape=(1,), dtype=np.float32)

    def step(self, action: Any) -> Any:
        obs, reward, terminated, truncated, info = super().step(action)
        t = info["time"]
        rows = [(t - 0.05, 3.1 + t, -0.2 * t), (t, 3.0 + t / 3, 0.1 / 7)]
        info["metrics"] = {"Cd": float(np.mean([r[1] for r in rows])), "Cl": rows[-1][2]}
        info["coefficients"] = np.asarray(rows)
        return obs, reward, terminated, truncated, info


class FilesPlugin:
    @hookimpl
    def gymprecice_register_environments(self, register):
        card = EnvCard(name="shifted", double=True, action_unit="W")
        register(SHIFTED, f"{__name__}:ShiftedEnv", card=card)
        register(FORCES, f"{__name__}:ForcesEnv", card=EnvCard(name="forces", double=True))


@pytest.fixture(scope="module", autouse=True)
def _envs():
    with temporary_plugin(FilesPlugin(), "labfiles-toys"):
        register_environments()
    yield
    for env_id in (SHIFTED, FORCES):
        gym.registry.pop(env_id, None)


def test_baseline_holds_the_zero_action_clipped_into_the_box(tmp_path: Path) -> None:
    """Not the middle of the box (1.25): zero, clipped to the box's lower bound."""
    assert main(["baseline", "shifted", "--double", "--out", str(tmp_path)]) == 0
    with (tmp_path / "history.csv").open() as handle:
        actions = [float(r["action_0"]) for r in csv.DictReader(handle)]
    assert actions == [0.5, 0.5, 0.5]


def test_no_coefficients_file_for_an_env_without_force_coefficients(tmp_path: Path) -> None:
    (tmp_path / "coefficients.csv").write_text("episode,time,Cd,Cl\n")  # an earlier run's
    assert main(["baseline", "shifted", "--double", "--out", str(tmp_path)]) == 0
    assert not (tmp_path / "coefficients.csv").exists()
    assert (tmp_path / "history.csv").exists() and (tmp_path / "summary.json").exists()


def test_a_cylinders_coefficients_file_is_unchanged(tmp_path: Path) -> None:
    """Byte for byte what the lab wrote before: ``episode,time,Cd,Cl`` and every row."""
    assert main(["baseline", "forces", "--double", "--episodes", "2", "--out", str(tmp_path)]) == 0
    env = ForcesEnv()
    expected = io.StringIO(newline="")
    writer = csv.writer(expected)
    writer.writerow(["episode", "time", "Cd", "Cl"])
    for episode in range(2):
        env.reset(seed=episode)
        for _ in range(3):
            for t, cd, cl in env.step(np.zeros(1, dtype=np.float32))[4]["coefficients"]:
                writer.writerow((episode, float(t), float(cd), float(cl)))
    assert (tmp_path / "coefficients.csv").read_bytes() == expected.getvalue().encode()
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert "series_mean_Cd" in summary["over_episodes"]


def _labels(monkeypatch) -> list[tuple[str, str]]:
    """Every axis's (x label, y label) of the figures saved from now on (a colour bar's
    label is its y label)."""
    saved: list[tuple[str, str]] = []

    def savefig(fig, *args: Any, **kwargs: Any) -> None:
        saved.extend((ax.get_xlabel(), ax.get_ylabel()) for ax in fig.axes)

    monkeypatch.setattr(matplotlib.figure.Figure, "savefig", savefig)
    return saved


def test_figures_name_the_cards_objective_and_action_unit(tmp_path: Path, monkeypatch) -> None:
    named = LabEnv("x/Named-v0", EnvCard(objective="tracking_error", action_unit="K"))
    unnamed = find_lab_env("shifted")  # no objective: the negated mean reward; unit W
    results = [
        SweepResult("uncontrolled", "uncontrolled", {}, [1.0, 2.0]),
        SweepResult("constant-0.5", "constant", {"action": 0.5}, [1.5, 1.0]),
        SweepResult("sine", "sinusoid", {"amplitude": 0.5, "frequency": 1.0}, [0.5, 0.7]),
    ]
    saved = _labels(monkeypatch)
    _figure(tmp_path / "sweep.png", results, named)
    (constant, sine, colour_bar) = saved
    assert constant == ("constant action (K)", "tracking_error (lower is better), mean over starts")
    assert colour_bar[1] == "tracking_error (lower is better)"
    assert "objective" not in " ".join(constant + sine + colour_bar)

    saved.clear()
    _figure(tmp_path / "sweep.png", results, unnamed)
    assert saved[0] == (
        "constant action (W)",
        "mean reward, negated (lower is better), mean over starts",
    )
    assert LabEnv("x/Max-v0", EnvCard(objective="lift", maximize=True)).objective_label == (
        "lift, negated (lower is better)"
    )

    saved.clear()
    scores = {"objective": {"scores": [[1.0, 2.0]]}}
    controllers = [{"label": "uncontrolled", "kind": "uncontrolled", "runs": 1, "metrics": scores}]
    plot_objective_per_start(tmp_path / "p.png", ["a", "b"], controllers, named.objective_label)
    assert saved == [("held-out start", "tracking_error (lower is better)")]


def _flat(text: str) -> str:
    return re.sub(r"\s+", " ", text.replace("#:", " "))


def test_uncontrolled_is_described_as_it_is_run(capsys) -> None:
    """The card's field, the Lab reference's table and ``baseline --help`` say one thing,
    what :func:`test_baseline_holds_the_zero_action_clipped_into_the_box` checks."""
    card_source = _flat(Path(gymprecice.card.__file__).read_text())
    assert UNCONTROLLED in _flat(gymprecice.card.__doc__ or "")
    assert f"default: none, the {UNCONTROLLED}" in card_source
    assert "mid-box" not in card_source
    (row,) = [
        line
        for line in (ROOT / "docs" / "reference" / "lab.md").read_text().splitlines()
        if line.startswith("| `uncontrolled` |")
    ]
    assert UNCONTROLLED in row
    with pytest.raises(SystemExit):
        main(["baseline", "--help"])
    assert UNCONTROLLED in _flat(capsys.readouterr().out)
