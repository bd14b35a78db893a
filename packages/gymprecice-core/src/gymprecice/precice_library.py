"""Old path of :mod:`gymprecice.tools.precice_library` (an alias: the same module object)."""

import sys

from gymprecice.tools import precice_library as _module

sys.modules[__name__] = _module
