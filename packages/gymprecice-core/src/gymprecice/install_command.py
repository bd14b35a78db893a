"""Old path of :mod:`gymprecice.tools.install_command` (an alias: the same module object)."""

import sys

from gymprecice.tools import install_command as _module

sys.modules[__name__] = _module
