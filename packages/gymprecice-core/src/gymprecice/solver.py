"""Old path of :mod:`gymprecice.plugin.solver` (an alias: the same module object)."""

import sys

from gymprecice.plugin import solver as _module

sys.modules[__name__] = _module
