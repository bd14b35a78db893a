"""The lab on an env that is not a tutorial: registered through the public hook, with or
without a lab card, its defaults derived from the env, its missing fields refused."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import warnings
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

from gymprecice.plugin.card import CardError, EnvCard, Reference, card_for, find_env
from gymprecice.plugin.hookspecs import hookimpl
from gymprecice.plugin.manager import PluginWarning, temporary_plugin
from gymprecice.plugin.registration import register_environments
from gymprecice.tools.cli import main
from gymprecice_lab.common.registered_env import default_frequency, find_lab_env

PLAIN = "labtest/Plain-v0"
CARDED = "labtest/Carded-v0"
BROKEN = "labtest/Broken-v0"


class ToyEnv(gym.Env):
    """Five actions an episode; the reward and the metric ``x`` are the action's size."""

    dt = 0.05  # one action every 0.05 s: a default forcing of 2 Hz

    def __init__(self, idx: int = 0, double: bool = False, **kwargs: Any) -> None:
        self.action_space = gym.spaces.Box(-1.0, 1.0, shape=(1,), dtype=np.float32)
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, shape=(2,), dtype=np.float32)
        self.steps = 0
        self.start = 0.0

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> Any:
        super().reset(seed=seed)
        self.steps, self.start = 0, float(self.np_random.uniform())
        return np.array([self.start, 0.0], dtype=np.float32), {"time": 0.0}

    def step(self, action: Any) -> Any:
        self.steps += 1
        size = float(np.abs(np.asarray(action)).mean())
        info = {"time": self.steps * self.dt, "metrics": {"x": size + self.start}}
        obs = np.array([self.start, size], dtype=np.float32)
        return obs, -size, False, self.steps >= 5, info


class ToyPlugin:
    @hookimpl
    def gymprecice_register_environments(self, register):
        register(PLAIN, f"{__name__}:ToyEnv")
        register(CARDED, f"{__name__}:ToyEnv", card=EnvCard(name="toy", double=True))
        register(BROKEN, f"{__name__}:ToyEnv", card={"objective": 3})


@pytest.fixture(scope="module", autouse=True)
def toy_envs():
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with temporary_plugin(ToyPlugin(), "labtest-toys"):
            register_environments()
    refusals = [str(w.message) for w in caught if issubclass(w.category, PluginWarning)]
    yield refusals
    for env_id in (PLAIN, CARDED, BROKEN):
        gym.registry.pop(env_id, None)


def test_a_malformed_card_is_refused_at_load_naming_package_and_field(toy_envs) -> None:
    (message,) = [m for m in toy_envs if BROKEN in m]
    assert "'labtest-toys'" in message and "'objective'" in message
    assert BROKEN in gym.registry  # the env itself stays usable
    with pytest.raises(CardError, match="objective"):
        card_for(BROKEN)


def test_ids_short_names_and_unknown_ids() -> None:
    assert find_env("toy") == (CARDED, card_for(CARDED))
    assert find_env("Plain-v0")[0] == PLAIN
    assert card_for(PLAIN) == EnvCard()
    with pytest.raises(KeyError, match=r"toy \(labtest/Carded-v0\).*labtest/Plain-v0"):
        find_env("no-such-env")


def test_card_fields_of_the_wrong_type_are_refused() -> None:
    with pytest.raises(CardError, match="'double'"):
        EnvCard(double="yes").check()  # type: ignore[arg-type]
    with pytest.raises(CardError, match="must differ"):
        EnvCard(reference=Reference(metric="Cd", uncontrolled=1.0, floor=1.0)).check()


def test_a_card_built_with_a_wrong_type_refuses_that_env_alone() -> None:
    """Built in the hook (not a mapping), the card must not break the hook: the env is
    registered and its refusal names the package and the field."""
    from gymprecice.plugin.card import record_card

    with pytest.raises(CardError, match=r"from package 'labtest-pkg'.*'double'"):
        record_card("labtest/Built-v0", EnvCard(double="yes"), "labtest-pkg")  # type: ignore[arg-type]
    with pytest.raises(CardError, match="'double'"):
        card_for("labtest/Built-v0")


def test_defaults_are_derived_from_the_env() -> None:
    env = find_lab_env(PLAIN)
    assert env.name == PLAIN and env.objective is None and env.open_loop_frequency is None
    assert default_frequency(ToyEnv()) == pytest.approx(2.0)
    assert default_frequency(object()) == 1.0


@pytest.mark.parametrize(
    ("argv", "field"),
    [
        (["feedback", PLAIN], "feedback_signal"),
        (["train", PLAIN, "--double"], "'double'"),
        (["time-to-floor", "RUN", "--env", "toy"], "'reference'"),
        (["evaluate", BROKEN], "'objective'"),
    ],
)
def test_a_command_needing_a_missing_field_is_refused_before_it_writes(
    argv: list[str], field: str, tmp_path: Path, capsys, monkeypatch
) -> None:
    monkeypatch.chdir(tmp_path)
    argv = [str(tmp_path / a) if a == "RUN" else a for a in argv]
    assert _status([*argv, "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and field in err[0], err
    assert not (tmp_path / "out").exists() and not (tmp_path / "runs").exists()


def _status(argv: list[str]) -> int:
    """``gymprecice ARGV``'s exit status, as the shell sees it."""
    try:
        return main(argv)
    except SystemExit as exc:
        return int(exc.code or 0)


def test_seeds_are_the_starts_of_an_env_without_held_out_ones(tmp_path: Path) -> None:
    assert main(["baseline", "toy", "--double", "--all-starts", "--out", str(tmp_path)]) == 0
    summary = json.loads((tmp_path / "summary.json").read_text())
    labels = [e["start_label"] for e in summary["episodes"]]
    assert labels == [f"seed {k}" for k in range(5)]
    assert "mean_x" in summary["over_episodes"]


def test_open_loop_forces_at_a_tenth_of_the_action_rate(tmp_path: Path) -> None:
    assert main(["open-loop", "toy", "--double", "--out", str(tmp_path)]) == 0
    manifest = json.loads((tmp_path / "manifest.json").read_text())
    assert manifest["settings"]["frequency"] == pytest.approx(2.0)


def test_the_lab_imports_no_tutorial_module() -> None:
    """Every lab module, imported with no plugin loaded: none of the tutorials comes along
    (a user trains an env of their own without the GPL-licensed tutorials)."""
    code = (
        "import importlib, pkgutil, sys, gymprecice_lab\n"
        "for m in pkgutil.walk_packages(gymprecice_lab.__path__, 'gymprecice_lab.'):\n"
        "    importlib.import_module(m.name)\n"
        "print(sorted(m for m in sys.modules if m.startswith('gymprecice_tutorials')))\n"
    )
    env = {**os.environ, "GYMPRECICE_DISABLE_PLUGINS": "1"}
    proc = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=300, env=env
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "[]"
