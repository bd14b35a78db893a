"""The old path of :mod:`gymprecice_lab.common.requirements`: the same module object."""

import sys

from gymprecice_lab.common import requirements as _module

sys.modules[__name__] = _module
