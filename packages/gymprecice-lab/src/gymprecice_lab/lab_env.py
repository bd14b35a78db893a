"""The old path of :mod:`gymprecice_lab.common.registered_env`: the same module object."""

import sys

from gymprecice_lab.common import registered_env as _module

sys.modules[__name__] = _module
