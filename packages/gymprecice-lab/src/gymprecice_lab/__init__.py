"""gymprecice's lab: train, evaluate, benchmark and judge controllers on any registered env.

The lab is built in wings, one sub-package each: :mod:`.cli` (the commands' parsers),
:mod:`.training` (train, tune), :mod:`.rollouts` (evaluate and the fixed controllers,
sweep, compare, plot), :mod:`.benchmarking` (benchmark, time-to-floor),
:mod:`.policies` (shipped and shipping policies), :mod:`.model_based` (model-ensemble
PPO) and :mod:`.common` (ENV and its card, the wrapped env, starts, manifests).

The flat module paths of earlier versions (``gymprecice_lab.train``,
``gymprecice_lab.evaluate``, ``gymprecice_lab.lab_env``, ...) still import: each is a
file of three lines that puts its new module in ``sys.modules`` under the old name, so
both names are the same module object (a monkeypatch on either is seen by both, and a
run pickled under an old name loads). New code imports the new paths.
"""
