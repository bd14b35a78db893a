"""Old path of :mod:`gymprecice.env.values` (an alias: the same module object)."""

import sys

from gymprecice.env import values as _module

sys.modules[__name__] = _module
