"""The old path of :mod:`gymprecice_lab.cli.options`: the same module object."""

import sys

from gymprecice_lab.cli import options as _module

sys.modules[__name__] = _module
