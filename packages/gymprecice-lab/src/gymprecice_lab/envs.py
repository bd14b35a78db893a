"""The old path of :mod:`gymprecice_lab.common.wrapped_env`: the same module object."""

import sys

from gymprecice_lab.common import wrapped_env as _module

sys.modules[__name__] = _module
