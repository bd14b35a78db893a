"""Old path of :mod:`gymprecice.env.precice_library` (an alias: the same module object)."""

import sys

from gymprecice.env import precice_library as _module

sys.modules[__name__] = _module
