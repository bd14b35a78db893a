"""Old path of :mod:`gymprecice.learners.sb3` (an alias: the same module object)."""

import sys

from gymprecice.learners import sb3 as _module

sys.modules[__name__] = _module
