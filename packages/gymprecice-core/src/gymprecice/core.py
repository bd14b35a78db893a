"""Old path of :mod:`gymprecice.env.core` (an alias: the same module object)."""

import sys

from gymprecice.env import core as _module

sys.modules[__name__] = _module
