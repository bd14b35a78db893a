"""The old path of :mod:`gymprecice_lab.training.kept_model`: the same module object."""

import sys

from gymprecice_lab.training import kept_model as _module

sys.modules[__name__] = _module
