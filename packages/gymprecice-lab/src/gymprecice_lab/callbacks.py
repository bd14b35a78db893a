"""The old path of :mod:`gymprecice_lab.training.callbacks`: the same module object."""

import sys

from gymprecice_lab.training import callbacks as _module

sys.modules[__name__] = _module
