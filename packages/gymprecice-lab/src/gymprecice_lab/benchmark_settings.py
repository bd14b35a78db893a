"""The old path of :mod:`gymprecice_lab.benchmarking.settings`: the same module object."""

import sys

from gymprecice_lab.benchmarking import settings as _module

sys.modules[__name__] = _module
