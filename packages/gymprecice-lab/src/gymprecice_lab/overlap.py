"""The old path of :mod:`gymprecice_lab.training.overlap`: the same module object."""

import sys

from gymprecice_lab.training import overlap as _module

sys.modules[__name__] = _module
