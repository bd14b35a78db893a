"""Old path of :mod:`gymprecice.plugin.registration` (an alias: the same module object)."""

import sys

from gymprecice.plugin import registration as _module

sys.modules[__name__] = _module
