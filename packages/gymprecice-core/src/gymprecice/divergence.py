"""Old path of :mod:`gymprecice.plugin.divergence` (an alias: the same module object)."""

import sys

from gymprecice.plugin import divergence as _module

sys.modules[__name__] = _module
