"""The old path of :mod:`gymprecice_lab.rollouts.feedback`: the same module object."""

import sys

from gymprecice_lab.rollouts import feedback as _module

sys.modules[__name__] = _module
