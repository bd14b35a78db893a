"""The old path of :mod:`gymprecice_lab.common.starts`: the same module object."""

import sys

from gymprecice_lab.common import starts as _module

sys.modules[__name__] = _module
