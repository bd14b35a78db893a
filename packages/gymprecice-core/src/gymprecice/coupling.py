"""Old path of :mod:`gymprecice.env.coupling` (an alias: the same module object)."""

import sys

from gymprecice.env import coupling as _module

sys.modules[__name__] = _module
