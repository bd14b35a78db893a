"""Old path of :mod:`gymprecice.env.processes` (an alias: the same module object)."""

import sys

from gymprecice.env import processes as _module

sys.modules[__name__] = _module
