"""The old path of :mod:`gymprecice_lab.training.segments`: the same module object."""

import sys

from gymprecice_lab.training import segments as _module

sys.modules[__name__] = _module
