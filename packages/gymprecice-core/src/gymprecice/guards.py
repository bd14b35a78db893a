"""Old path of :mod:`gymprecice.env.guards` (an alias: the same module object)."""

import sys

from gymprecice.env import guards as _module

sys.modules[__name__] = _module
