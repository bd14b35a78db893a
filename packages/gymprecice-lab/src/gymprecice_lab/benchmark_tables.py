"""The old path of :mod:`gymprecice_lab.benchmarking.tables`: the same module object."""

import sys

from gymprecice_lab.benchmarking import tables as _module

sys.modules[__name__] = _module
