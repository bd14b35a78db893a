"""Adapters to the learning libraries: Stable-Baselines3, RLlib, robustness wrappers.

:mod:`~gymprecice.learners.sb3` (a resilient ``SubprocVecEnv`` over
:mod:`gymprecice.vector`, and a callback that logs its telemetry),
:mod:`~gymprecice.learners.rllib` (an env creator for RLlib) and
:mod:`~gymprecice.learners.robustness` (perturbed envs for robustness studies).

This package's ``__init__`` imports nothing: each adapter needs its optional library.
"""
