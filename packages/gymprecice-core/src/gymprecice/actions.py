"""Old path of :mod:`gymprecice.env.actions` (an alias: the same module object)."""

import sys

from gymprecice.env import actions as _module

sys.modules[__name__] = _module
