"""The old path of :mod:`gymprecice_lab.policies.policy`: the same module object."""

import sys

from gymprecice_lab.policies import policy as _module

sys.modules[__name__] = _module
