"""Old path of :mod:`gymprecice.env.rendering` (an alias: the same module object)."""

import sys

from gymprecice.env import rendering as _module

sys.modules[__name__] = _module
