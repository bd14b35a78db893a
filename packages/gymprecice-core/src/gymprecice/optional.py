"""Old path of :mod:`gymprecice.tools.optional` (an alias: the same module object)."""

import sys

from gymprecice.tools import optional as _module

sys.modules[__name__] = _module
