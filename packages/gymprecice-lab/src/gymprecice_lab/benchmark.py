"""The old path of :mod:`gymprecice_lab.benchmarking.command`: the same module object."""

import sys

from gymprecice_lab.benchmarking import command as _module

sys.modules[__name__] = _module
