"""The old path of :mod:`gymprecice_lab.training.tune_spaces`: the same module object."""

import sys

from gymprecice_lab.training import tune_spaces as _module

sys.modules[__name__] = _module
