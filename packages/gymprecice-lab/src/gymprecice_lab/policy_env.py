"""The old path of :mod:`gymprecice_lab.policies.fitted_env`: the same module object."""

import sys

from gymprecice_lab.policies import fitted_env as _module

sys.modules[__name__] = _module
