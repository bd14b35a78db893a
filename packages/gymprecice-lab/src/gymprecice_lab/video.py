"""The old path of :mod:`gymprecice_lab.rollouts.video`: the same module object."""

import sys

from gymprecice_lab.rollouts import video as _module

sys.modules[__name__] = _module
