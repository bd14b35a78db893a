"""Old path of :mod:`gymprecice.plugin.sketch` (an alias: the same module object)."""

import sys

from gymprecice.plugin import sketch as _module

sys.modules[__name__] = _module
