"""Old path of :mod:`gymprecice.env.exit_cleanup` (an alias: the same module object)."""

import sys

from gymprecice.env import exit_cleanup as _module

sys.modules[__name__] = _module
