"""Old path of :mod:`gymprecice.tools.case_sketch` (an alias: the same module object)."""

import sys

from gymprecice.tools import case_sketch as _module

sys.modules[__name__] = _module
