"""The old path of :mod:`gymprecice_lab.common.wrapping`: the same module object."""

import sys

from gymprecice_lab.common import wrapping as _module

sys.modules[__name__] = _module
