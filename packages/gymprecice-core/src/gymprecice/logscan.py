"""Old path of :mod:`gymprecice.plugin.logscan` (an alias: the same module object)."""

import sys

from gymprecice.plugin import logscan as _module

sys.modules[__name__] = _module
