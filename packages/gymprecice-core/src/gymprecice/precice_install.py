"""Old path of :mod:`gymprecice.tools.precice_install` (an alias: the same module object)."""

import sys

from gymprecice.tools import precice_install as _module

sys.modules[__name__] = _module
