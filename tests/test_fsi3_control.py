"""FSI3 as a registered control env (``gymprecice/TurekHronFSI3-v0``), without solvers.

Its lab card, the library of starts it looks for (and the error that names the folder and
the build command when there is none), the reward on synthetic tip and force rows, and
the shut jets of ``uncontrolled=True``. The coupled episode from a start is
tests/test_fsi3_real.py's.
"""

from __future__ import annotations

import math
from pathlib import Path
from types import SimpleNamespace

import gymnasium as gym
import numpy as np
import pytest

import gymprecice  # noqa: F401  (registers the ids)
from gymprecice.plugin.card import card_for, find_env
from gymprecice_tutorials.turek_hron import starts
from gymprecice_tutorials.turek_hron.environment import (
    A_REF,
    DRAG_REF,
    TurekHronControlEnv,
    TurekHronEnv,
    reward_terms,
)
from gymprecice_tutorials.turek_hron.reference import PUBLISHED
from tests.test_fsi3_starts import _library

ENV_ID = "gymprecice/TurekHronFSI3-v0"


@pytest.fixture
def data_home(tmp_path, monkeypatch) -> Path:
    """An empty ``XDG_DATA_HOME``: no library where the registered env looks."""
    home = tmp_path / "data"
    monkeypatch.setenv("XDG_DATA_HOME", str(home))
    return home


def test_the_registered_id_is_the_control_env_with_its_lab_card() -> None:
    assert gym.spec(ENV_ID).entry_point == (
        "gymprecice_tutorials.turek_hron.environment:TurekHronControlEnv"
    )
    assert find_env("turek-hron-fsi3")[0] == ENV_ID
    card = card_for(ENV_ID)
    assert card.objective == "cost" and not card.maximize
    assert card.metrics == ("mean_abs_tip_dy", "drag")
    assert card.held_out_starts and card.validation_starts
    assert card.uncontrolled == {"uncontrolled": True}
    assert card.open_loop_frequency == PUBLISHED["tip_dy_frequency"].value  # the bar's swing
    assert card.action_unit == "m³/s"
    assert {"pyprecice", "openfoam", "fenics"} <= set(card.checks_for({}))
    assert card.episode_time and not card.double  # no test double for FSI3
    assert card.policies == "gymprecice_tutorials:policies"


def test_the_default_library_is_under_the_users_data_folder(tmp_path, monkeypatch) -> None:
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "xdg"))
    assert starts.default_starts() == tmp_path / "xdg" / "gymprecice" / "turek-hron-fsi3" / "starts"
    monkeypatch.delenv("XDG_DATA_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    expected = tmp_path / "home" / ".local" / "share" / "gymprecice" / "turek-hron-fsi3" / "starts"
    assert starts.default_starts() == expected


def test_the_build_puts_the_library_where_the_env_looks_by_default(data_home, monkeypatch):
    from gymprecice_tutorials.turek_hron import build_starts

    asked: dict = {}

    def build(out, **kwargs):
        asked["out"] = out
        raise ValueError("stop here")

    monkeypatch.setattr(build_starts, "build", build)
    assert build_starts.main(["--smoke"]) == 1
    assert asked["out"] == starts.default_starts()


def test_without_a_library_the_registered_env_names_the_folder_and_the_command(
    data_home, tmp_path
) -> None:
    with pytest.raises(FileNotFoundError) as caught:
        gym.make(ENV_ID, run_root=str(tmp_path / "runs"))
    said = str(caught.value)
    assert str(starts.default_starts()) in said
    assert "python -m gymprecice_tutorials.turek_hron.build_starts" in said
    assert starts.BUILD_COST in said and "starts=DIR" in said
    assert not (tmp_path / "runs").exists()  # refused before any case is written


def test_the_registered_env_starts_from_the_default_library_or_the_one_it_is_given(
    data_home, tmp_path
) -> None:
    library = _library(starts.default_starts())
    env = TurekHronControlEnv(run_root=tmp_path / "runs")
    assert env.starts.path == library.resolve() and env.held_out_starts
    elsewhere = _library(tmp_path / "elsewhere", times=["6", "6.02", "6.04", "6.06"])
    assert TurekHronControlEnv(starts=elsewhere, run_root=tmp_path / "r2").starts.path == elsewhere
    from_rest = TurekHronControlEnv(starts=None, run_root=tmp_path / "r3")
    assert from_rest.starts is None and from_rest.held_out_starts == ()
    assert TurekHronEnv(run_root=tmp_path / "r4").starts is None  # the class keeps its default


class _Tip:
    """A watch-point reader's rows: time, then the tip's displacement (dx, dy)."""

    def __init__(self, rows: np.ndarray) -> None:
        self.data = rows

    def field(self, name: str, rows: np.ndarray | None = None) -> np.ndarray:
        assert name == "Displacement"
        return (self.data if rows is None else rows)[:, 1:3]


def _stubbed(env: TurekHronEnv, dy: list[float], drag: float, lift: float = 3.0) -> None:
    """The env's step as read: a window's tip rows and the step's mean forces."""
    rows = np.array([[0.002 * (k + 1), 1e-4, value] for k, value in enumerate(dy)])
    env._tip = _Tip(rows)
    env._step_rows = rows
    env.forces = lambda: (drag, lift)  # type: ignore[method-assign]


@pytest.mark.parametrize(
    ("dy", "drag", "weight"),
    [
        ([0.01, -0.03, 0.02], 450.0, 1.0),  # drag below the benchmark's: no penalty
        ([0.01, -0.03, 0.02], 500.0, 1.0),
        ([-0.034, 0.0], 480.0, 2.5),
        ([0.0, 0.0], DRAG_REF, 1.0),  # still, at the benchmark's drag: no cost at all
    ],
)
def test_the_reward_is_the_swing_over_the_benchmarks_and_the_drag_above_its_mean(
    tmp_path, monkeypatch, dy, drag, weight
) -> None:
    from gymprecice.env.core import Adapter

    assert PUBLISHED["tip_dy_amplitude"].value == A_REF
    assert PUBLISHED["drag_mean"].value == DRAG_REF
    env = TurekHronEnv(run_root=tmp_path / "runs", drag_weight=weight)
    _stubbed(env, dy, drag)
    swing = float(np.mean(np.abs(dy))) / PUBLISHED["tip_dy_amplitude"].value
    penalty = weight * max(0.0, drag / PUBLISHED["drag_mean"].value - 1.0)
    assert env._get_reward() == pytest.approx(-swing - penalty, rel=1e-12, abs=1e-15)
    assert reward_terms(np.mean(np.abs(dy)), drag, weight) == pytest.approx((swing, penalty))

    # step's metrics: the tip and forces as before, and the reward's two terms
    def step(self, action):
        return np.array([1e-4, dy[-1]], np.float32), self._get_reward(), False, False, {}

    monkeypatch.setattr(Adapter, "step", step)
    _, reward, *_, info = env.step(np.zeros(1, np.float32))
    metrics = info["metrics"]
    assert metrics["mean_abs_tip_dy"] == pytest.approx(np.mean(np.abs(dy)))
    assert metrics["drag"] == drag and metrics["lift"] == 3.0
    assert metrics["swing"] == pytest.approx(swing)
    assert metrics["drag_penalty"] == pytest.approx(penalty)
    assert metrics["cost"] == pytest.approx(-reward)


def test_a_step_without_force_rows_has_a_nan_reward_for_the_guards(tmp_path) -> None:
    env = TurekHronEnv(run_root=tmp_path / "runs")
    _stubbed(env, [0.01], math.nan, math.nan)
    assert math.isnan(env._get_reward())


def test_a_negative_drag_weight_is_refused_before_any_case_is_written(tmp_path) -> None:
    with pytest.raises(ValueError, match="drag_weight"):
        TurekHronEnv(run_root=tmp_path / "runs", drag_weight=-1.0)
    assert not (tmp_path / "runs").exists()


def _jet_faces(angle: float) -> SimpleNamespace:
    """Faces of a jet on the cylinder, centred at ``angle`` (degrees), one cell deep."""
    from gymprecice_tutorials.turek_hron.mesh import GEOMETRY

    angles = np.radians(angle + np.linspace(-4.0, 4.0, 5))
    out = np.stack([np.cos(angles), np.sin(angles), np.zeros_like(angles)], axis=1)
    return SimpleNamespace(
        coordinates=np.asarray((*GEOMETRY.centre, 0.0)) + GEOMETRY.radius * out,
        normals=-out,  # out of the fluid, into the cylinder
        areas=np.full(len(angles), 1e-4),
    )


def test_uncontrolled_sends_no_flow_whatever_the_action(tmp_path, monkeypatch) -> None:
    jets = {"jet1": _jet_faces(90.0), "jet2": _jet_faces(270.0)}
    monkeypatch.setattr(TurekHronEnv, "interface_geometry", property(lambda self: jets))
    controlled = TurekHronEnv(run_root=tmp_path / "a")
    shut = TurekHronEnv(run_root=tmp_path / "b", uncontrolled=True)
    bound = controlled.max_flow_rate
    assert controlled.flow_rate([bound / 2]) == pytest.approx(bound / 2)
    opened = controlled._get_action(np.asarray([bound], np.float32), [])
    assert all(np.any(velocity) for velocity in opened.values())
    for action in ([bound], [-bound], [0.3 * bound], [10.0]):
        assert shut.flow_rate(action) == 0.0
        written = shut._get_action(np.asarray(action, np.float32), [])
        assert set(written) == set(jets)
        assert all(not np.any(velocity) for velocity in written.values())
