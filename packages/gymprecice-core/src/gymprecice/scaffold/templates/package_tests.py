"""The new package's own tests: ``tests/test_env.py`` (``gymprecice check`` on the case,
the registration with its lab card, Gymnasium's checker and an episode on the test double)
and, with ``--solver-plugin``, ``tests/test_conformance.py`` (gymprecice's plugin
conformance suite on the package's solver kind).
"""

from __future__ import annotations

__all__ = ["CONFORMANCE_TESTS", "TESTS"]

TESTS = '''\
"""{{env_id}}: the case passes ``gymprecice check``, the env registers with its lab card,
and it passes Gymnasium's checker on the test double (no preCICE, no solver needed)."""

from __future__ import annotations

import warnings

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from gymprecice.card import card_for
from gymprecice.cli import main

from {{module}}.env import CASE_DIR
from {{module}}.plugin import ENV_ID


def test_registered_with_its_card() -> None:
    import gymprecice  # noqa: F401  (registers every installed package's envs)

    assert ENV_ID in gymnasium.registry
    card = card_for(ENV_ID)
    assert card.double and card.objective == "tracking_error"


def test_the_case_passes_gymprecice_check() -> None:
    assert main(["check", str(CASE_DIR)]) == 0


@pytest.fixture
def env(tmp_path):
    env = gymnasium.make(ENV_ID, double=True, run_root=tmp_path).unwrapped
    yield env
    env.close()


def test_check_env_on_the_double(env) -> None:
    with warnings.catch_warnings():
        # the checker advises finite observation bounds; these are unbounded on purpose
        warnings.simplefilter("ignore")
        check_env(env, skip_render_check=True)


def test_an_episode_on_the_double(env) -> None:
    env.reset(seed=0)
    steps, terminated, truncated = 0, False, False
    while not (terminated or truncated):
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        steps += 1
    assert truncated and not terminated and steps == {{steps}}
    assert obs.shape == env.observation_space.shape and np.isfinite(reward)
    assert set(info["metrics"]) == {"tracking_error", "sensed", "actuation"}
'''

CONFORMANCE_TESTS = '''\
"""The package's solver kind against gymprecice's plugin conformance suite: the hooks
answer None for another kind, write only under the env's run directory, and launch
inside it."""

from __future__ import annotations

import shutil

import pytest
from gymprecice.testing.conformance import (
    SolverPluginConformance,
    make_solver_context,
)

from {{module}}.env import CASE_DIR, SOLVER
from {{module}}.plugin import KIND, PARTICIPANT


class TestSolverKindConformance(SolverPluginConformance):
    @pytest.fixture
    def plugin(self):
        from {{module}} import plugin

        return plugin

    @pytest.fixture
    def kind(self) -> str:
        return KIND

    @pytest.fixture
    def make_solver(self):
        def make(base):
            source = base / "case" / "{{solver_dir}}"
            shutil.copytree(CASE_DIR / "{{solver_dir}}", source)
            return make_solver_context(
                KIND,
                source,
                base,
                name=SOLVER,
                participant=PARTICIPANT,
                precice_config=CASE_DIR / "precice-config.xml",
            )

        return make
'''
