"""Old path of :mod:`gymprecice.vector.telemetry` (an alias: the same module object)."""

import sys

from gymprecice.vector import telemetry as _module

sys.modules[__name__] = _module
