"""Old path of :mod:`gymprecice.env.default_plugin` (an alias: the same module object)."""

import sys

from gymprecice.env import default_plugin as _module

sys.modules[__name__] = _module
