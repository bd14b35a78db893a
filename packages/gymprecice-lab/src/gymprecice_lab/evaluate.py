"""The old path of :mod:`gymprecice_lab.rollouts.evaluate`: the same module object."""

import sys

from gymprecice_lab.rollouts import evaluate as _module

sys.modules[__name__] = _module
