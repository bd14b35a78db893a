"""Old path of :mod:`gymprecice.plugin.options` (an alias: the same module object)."""

import sys

from gymprecice.plugin import options as _module

sys.modules[__name__] = _module
