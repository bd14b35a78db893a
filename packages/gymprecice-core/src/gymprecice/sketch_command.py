"""Old path of :mod:`gymprecice.tools.sketch_command` (an alias: the same module object)."""

import sys

from gymprecice.tools import sketch_command as _module

sys.modules[__name__] = _module
