"""The old path of :mod:`gymprecice_lab.training.train`: the same module object."""

import sys

from gymprecice_lab.training import train as _module

sys.modules[__name__] = _module
