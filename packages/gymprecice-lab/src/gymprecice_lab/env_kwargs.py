"""The old path of :mod:`gymprecice_lab.common.constructor_kwargs`: the same module object."""

import sys

from gymprecice_lab.common import constructor_kwargs as _module

sys.modules[__name__] = _module
