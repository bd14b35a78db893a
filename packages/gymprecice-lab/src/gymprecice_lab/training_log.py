"""The old path of :mod:`gymprecice_lab.training.logger`: the same module object."""

import sys

from gymprecice_lab.training import logger as _module

sys.modules[__name__] = _module
