"""The old path of :mod:`gymprecice_lab.training.shared_policy`: the same module object."""

import sys

from gymprecice_lab.training import shared_policy as _module

sys.modules[__name__] = _module
