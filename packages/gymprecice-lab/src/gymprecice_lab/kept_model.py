"""The old path of :mod:`gymprecice_lab.common.kept_model`: the same module object."""

import sys

from gymprecice_lab.common import kept_model as _module

sys.modules[__name__] = _module
