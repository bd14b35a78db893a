"""The old path of :mod:`gymprecice_lab.policies.shipped`: the same module object."""

import sys

from gymprecice_lab.policies import shipped as _module

sys.modules[__name__] = _module
