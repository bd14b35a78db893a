"""The old path of :mod:`gymprecice_lab.training.tune`: the same module object."""

import sys

from gymprecice_lab.training import tune as _module

sys.modules[__name__] = _module
