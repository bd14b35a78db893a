"""The old path of :mod:`gymprecice_lab.benchmarking.argv`: the same module object."""

import sys

from gymprecice_lab.benchmarking import argv as _module

sys.modules[__name__] = _module
