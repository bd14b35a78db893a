"""The old path of :mod:`gymprecice_lab.policies.slim_model`: the same module object."""

import sys

from gymprecice_lab.policies import slim_model as _module

sys.modules[__name__] = _module
