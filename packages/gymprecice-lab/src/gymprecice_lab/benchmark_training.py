"""The old path of :mod:`gymprecice_lab.benchmarking.seed_training`: the same module object."""

import sys

from gymprecice_lab.benchmarking import seed_training as _module

sys.modules[__name__] = _module
