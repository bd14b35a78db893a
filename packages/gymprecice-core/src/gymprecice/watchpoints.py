"""Old path of :mod:`gymprecice.plugin.watchpoints` (an alias: the same module object)."""

import sys

from gymprecice.plugin import watchpoints as _module

sys.modules[__name__] = _module
