"""The old path of :mod:`gymprecice_lab.benchmarking.time_to_floor`: the same module object."""

import sys

from gymprecice_lab.benchmarking import time_to_floor as _module

sys.modules[__name__] = _module
