"""gymprecice: Gymnasium environments from preCICE-coupled PDE simulations.

Importing the package registers the Gymnasium environment ids of every installed plugin
(see :mod:`gymprecice.registration`), so ``gymnasium.make("gymprecice/...")`` works
without importing the plugin packages by hand.

The flat module paths of earlier versions (``gymprecice.core``, ``gymprecice.errors``,
...) still import, as the modules that now hold them (:mod:`gymprecice.old_paths`).
"""

import os

from gymprecice.old_paths import MOVED as _MOVED
from gymprecice.old_paths import install as _answer_old_paths

__version__ = "0.2.0"

# Before anything else imports: plugins written against the old paths load through it.
_answer_old_paths(_MOVED)


def _register_plugin_environments() -> None:
    # Never let plugin trouble make ``import gymprecice`` fail: registration already
    # reports each broken plugin; this guards the plugin manager itself.
    import warnings

    try:
        from gymprecice.plugin.registration import register_environments

        register_environments()
    except Exception as exc:  # pragma: no cover - defensive
        warnings.warn(
            f"gymprecice could not register plugin environments: {type(exc).__name__}: {exc}",
            RuntimeWarning,
            stacklevel=2,
        )


# With every third-party plugin disabled (coupling workers, partners, hermetic tests) there
# is nothing to register, and skipping it keeps their start-up free of gymnasium.
if os.environ.get("GYMPRECICE_DISABLE_PLUGINS", "").strip().lower() not in (
    "1",
    "true",
    "all",
    "*",
):
    _register_plugin_environments()
