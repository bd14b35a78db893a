"""Old path of :mod:`gymprecice.tools.clean_command` (an alias: the same module object)."""

import sys

from gymprecice.tools import clean_command as _module

sys.modules[__name__] = _module
