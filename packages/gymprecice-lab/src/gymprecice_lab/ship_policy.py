"""The old path of :mod:`gymprecice_lab.policies.ship`: the same module object."""

import sys

from gymprecice_lab.policies import ship as _module

sys.modules[__name__] = _module
