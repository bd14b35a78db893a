"""The env runtime: one Gymnasium env coupled to its solvers, from ``Adapter`` down.

:class:`gymprecice.env.core.Adapter` is the env class a project subclasses. Below it:
the episode (:mod:`~gymprecice.env.episode`: reset, step, close), the coupled run
(:mod:`~gymprecice.env.coupled_run`: the solvers and the coupling worker of one
episode), the coupling session with the worker process (:mod:`~gymprecice.env.coupling`),
the solver processes and their records (:mod:`~gymprecice.env.processes` names the
modules that start, wait for and end them; :mod:`~gymprecice.env.pidregistry`,
:mod:`~gymprecice.env.owner_watchdog`), the step's
guards (with :mod:`~gymprecice.env.precice_library`: which preCICE a solver loaded),
actions, values and frames, the run directory and the configuration, and core's own
plugin for the kinds ``script`` and ``command`` (:mod:`~gymprecice.env.default_plugin`).

This package's ``__init__`` imports nothing: a module of it is imported by name.
"""
