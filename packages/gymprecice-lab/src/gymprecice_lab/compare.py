"""The old path of :mod:`gymprecice_lab.rollouts.compare`: the same module object."""

import sys

from gymprecice_lab.rollouts import compare as _module

sys.modules[__name__] = _module
