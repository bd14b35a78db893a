"""Old path of :mod:`gymprecice.env.episode` (an alias: the same module object)."""

import sys

from gymprecice.env import episode as _module

sys.modules[__name__] = _module
