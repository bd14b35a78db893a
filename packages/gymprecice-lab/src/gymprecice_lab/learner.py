"""The old path of :mod:`gymprecice_lab.training.learner`: the same module object."""

import sys

from gymprecice_lab.training import learner as _module

sys.modules[__name__] = _module
