"""gymprecice's lab: train, evaluate, benchmark and judge controllers on any registered env.

The lab is built in wings, one sub-package each: :mod:`.cli` (the commands' parsers),
:mod:`.training` (train, tune), :mod:`.rollouts` (evaluate and the fixed controllers,
sweep, compare, plot), :mod:`.benchmarking` (benchmark, time-to-floor),
:mod:`.policies` (shipped and shipping policies), :mod:`.model_based` (model-ensemble
PPO) and :mod:`.common` (ENV and its card, the wrapped env, starts, manifests).

The flat module paths of earlier versions (``gymprecice_lab.train``,
``gymprecice_lab.evaluate``, ``gymprecice_lab.lab_env``, ...) still import: importing the
lab installs a finder for its table (:mod:`gymprecice_lab.old_paths`), which answers each
old path with its new module, so both names are the same module object (a monkeypatch on
either is seen by both, and a run pickled under an old name loads). New code imports the
new paths.
"""

from gymprecice.old_paths import install as _answer_old_paths
from gymprecice_lab.old_paths import MOVED as _MOVED

_answer_old_paths(_MOVED)
