"""Old path of :mod:`gymprecice.env.rundir` (an alias: the same module object)."""

import sys

from gymprecice.env import rundir as _module

sys.modules[__name__] = _module
