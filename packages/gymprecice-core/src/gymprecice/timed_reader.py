"""Old path of :mod:`gymprecice.env.timed_reader` (an alias: the same module object)."""

import sys

from gymprecice.env import timed_reader as _module

sys.modules[__name__] = _module
