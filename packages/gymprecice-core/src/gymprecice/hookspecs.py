"""Old path of :mod:`gymprecice.plugin.hookspecs` (an alias: the same module object)."""

import sys

from gymprecice.plugin import hookspecs as _module

sys.modules[__name__] = _module
