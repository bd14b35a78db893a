"""The old path of :mod:`gymprecice_lab.training.loop`: the same module object."""

import sys

from gymprecice_lab.training import loop as _module

sys.modules[__name__] = _module
