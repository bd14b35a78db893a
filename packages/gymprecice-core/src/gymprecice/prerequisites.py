"""Old path of :mod:`gymprecice.tools.prerequisites` (an alias: the same module object)."""

import sys

from gymprecice.tools import prerequisites as _module

sys.modules[__name__] = _module
