"""Adapters to the learning libraries: Stable-Baselines3, RLlib, and what training reads.

:mod:`~gymprecice.learners.sb3` (a resilient ``SubprocVecEnv`` and a telemetry callback),
:mod:`~gymprecice.learners.rllib` (an env creator for RLlib),
:mod:`~gymprecice.learners.robustness` (perturbed envs for robustness studies) and
:mod:`~gymprecice.learners.telemetry` (what an env reports per step and episode).

This package's ``__init__`` imports nothing: each adapter needs its optional library.
"""
