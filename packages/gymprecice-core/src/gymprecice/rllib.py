"""Old path of :mod:`gymprecice.learners.rllib` (an alias: the same module object)."""

import sys

from gymprecice.learners import rllib as _module

sys.modules[__name__] = _module
