"""Old path of :mod:`gymprecice.env.action_shaping` (an alias: the same module object)."""

import sys

from gymprecice.env import action_shaping as _module

sys.modules[__name__] = _module
