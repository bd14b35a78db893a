"""The old path of :mod:`gymprecice_lab.benchmarking.stats`: the same module object."""

import sys

from gymprecice_lab.benchmarking import stats as _module

sys.modules[__name__] = _module
