"""The old path of :mod:`gymprecice_lab.benchmarking.scores`: the same module object."""

import sys

from gymprecice_lab.benchmarking import scores as _module

sys.modules[__name__] = _module
