"""Old path of :mod:`gymprecice.env.pidregistry` (an alias: the same module object)."""

import sys

from gymprecice.env import pidregistry as _module

sys.modules[__name__] = _module
