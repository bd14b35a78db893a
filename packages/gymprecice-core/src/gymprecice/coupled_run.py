"""Old path of :mod:`gymprecice.env.coupled_run` (an alias: the same module object)."""

import sys

from gymprecice.env import coupled_run as _module

sys.modules[__name__] = _module
