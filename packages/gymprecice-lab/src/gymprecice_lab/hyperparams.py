"""The old path of :mod:`gymprecice_lab.training.hyperparams`: the same module object."""

import sys

from gymprecice_lab.training import hyperparams as _module

sys.modules[__name__] = _module
