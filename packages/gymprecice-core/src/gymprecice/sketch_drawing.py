"""Old path of :mod:`gymprecice.tools.sketch_drawing` (an alias: the same module object)."""

import sys

from gymprecice.tools import sketch_drawing as _module

sys.modules[__name__] = _module
