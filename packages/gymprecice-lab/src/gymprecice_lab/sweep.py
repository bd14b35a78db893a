"""The old path of :mod:`gymprecice_lab.rollouts.sweep`: the same module object."""

import sys

from gymprecice_lab.rollouts import sweep as _module

sys.modules[__name__] = _module
