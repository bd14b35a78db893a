"""Old path of :mod:`gymprecice.plugin.readers` (an alias: the same module object)."""

import sys

from gymprecice.plugin import readers as _module

sys.modules[__name__] = _module
