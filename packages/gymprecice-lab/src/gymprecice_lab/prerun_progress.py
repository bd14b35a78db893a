"""The old path of :mod:`gymprecice_lab.training.prerun_progress`: the same module object."""

import sys

from gymprecice_lab.training import prerun_progress as _module

sys.modules[__name__] = _module
