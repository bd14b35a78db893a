"""Old path of :mod:`gymprecice.env.returned_values` (an alias: the same module object)."""

import sys

from gymprecice.env import returned_values as _module

sys.modules[__name__] = _module
