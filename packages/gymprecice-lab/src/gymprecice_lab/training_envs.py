"""The old path of :mod:`gymprecice_lab.training.vector_env`: the same module object."""

import sys

from gymprecice_lab.training import vector_env as _module

sys.modules[__name__] = _module
