"""Old path of :mod:`gymprecice.env.config` (an alias: the same module object)."""

import sys

from gymprecice.env import config as _module

sys.modules[__name__] = _module
