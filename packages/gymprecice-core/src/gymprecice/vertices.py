"""Old path of :mod:`gymprecice.env.vertices` (an alias: the same module object)."""

import sys

from gymprecice.env import vertices as _module

sys.modules[__name__] = _module
