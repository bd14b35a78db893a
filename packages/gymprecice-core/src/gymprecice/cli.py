"""Old path of :mod:`gymprecice.tools.cli` (an alias: the same module object)."""

import sys

from gymprecice.tools import cli as _module

sys.modules[__name__] = _module
