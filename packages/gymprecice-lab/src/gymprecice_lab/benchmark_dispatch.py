"""The old path of :mod:`gymprecice_lab.benchmarking.dispatch`: the same module object."""

import sys

from gymprecice_lab.benchmarking import dispatch as _module

sys.modules[__name__] = _module
