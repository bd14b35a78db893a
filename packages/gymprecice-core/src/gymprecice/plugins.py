"""Old path of :mod:`gymprecice.plugin.manager` (an alias: the same module object)."""

import sys

from gymprecice.plugin import manager as _module

sys.modules[__name__] = _module
