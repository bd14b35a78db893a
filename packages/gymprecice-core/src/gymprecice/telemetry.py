"""Old path of :mod:`gymprecice.learners.telemetry` (an alias: the same module object)."""

import sys

from gymprecice.learners import telemetry as _module

sys.modules[__name__] = _module
