"""Old path of :mod:`gymprecice.plugin.errors` (an alias: the same module object)."""

import sys

from gymprecice.plugin import errors as _module

sys.modules[__name__] = _module
