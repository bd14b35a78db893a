"""Old path of :mod:`gymprecice.tools.distribution` (an alias: the same module object)."""

import sys

from gymprecice.tools import distribution as _module

sys.modules[__name__] = _module
