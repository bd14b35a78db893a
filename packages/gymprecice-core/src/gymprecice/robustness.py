"""Old path of :mod:`gymprecice.learners.robustness` (an alias: the same module object)."""

import sys

from gymprecice.learners import robustness as _module

sys.modules[__name__] = _module
