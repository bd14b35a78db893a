"""Old path of :mod:`gymprecice.plugin.card` (an alias: the same module object)."""

import sys

from gymprecice.plugin import card as _module

sys.modules[__name__] = _module
