"""The old path of :mod:`gymprecice_lab.benchmarking.checks`: the same module object."""

import sys

from gymprecice_lab.benchmarking import checks as _module

sys.modules[__name__] = _module
