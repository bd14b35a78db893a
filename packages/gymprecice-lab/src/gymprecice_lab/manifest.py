"""The old path of :mod:`gymprecice_lab.common.manifest`: the same module object."""

import sys

from gymprecice_lab.common import manifest as _module

sys.modules[__name__] = _module
