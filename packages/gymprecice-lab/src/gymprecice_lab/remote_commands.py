"""The old path of :mod:`gymprecice_lab.benchmarking.remote_commands`: the same module object."""

import sys

from gymprecice_lab.benchmarking import remote_commands as _module

sys.modules[__name__] = _module
