"""The old path of :mod:`gymprecice_lab.training.validation`: the same module object."""

import sys

from gymprecice_lab.training import validation as _module

sys.modules[__name__] = _module
