"""Old path of :mod:`gymprecice.env.lifecycle` (an alias: the same module object)."""

import sys

from gymprecice.env import lifecycle as _module

sys.modules[__name__] = _module
