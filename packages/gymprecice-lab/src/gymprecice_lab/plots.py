"""The old path of :mod:`gymprecice_lab.rollouts.plots`: the same module object."""

import sys

from gymprecice_lab.rollouts import plots as _module

sys.modules[__name__] = _module
