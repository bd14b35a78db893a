"""Old path of :mod:`gymprecice.env.frames` (an alias: the same module object)."""

import sys

from gymprecice.env import frames as _module

sys.modules[__name__] = _module
