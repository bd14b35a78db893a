"""Old path of :mod:`gymprecice.tools.stack` (an alias: the same module object)."""

import sys

from gymprecice.tools import stack as _module

sys.modules[__name__] = _module
