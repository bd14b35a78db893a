"""The old path of :mod:`gymprecice_lab.benchmarking.plots`: the same module object."""

import sys

from gymprecice_lab.benchmarking import plots as _module

sys.modules[__name__] = _module
